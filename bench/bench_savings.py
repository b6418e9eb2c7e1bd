"""What each "model only what the scene requires" saving buys, and what it changes: time with and without, output
difference, on the fixed scenes of bench_tradeoff.py.

    python bench/bench_savings.py                     # 256x256, 3 repeats, both scenes (~10 min on a busy 2-core box)
    python bench/bench_savings.py --resolution 128 --repeats 1 --check-spp 0   # a quick look
    python bench/bench_savings.py --only depth --resolution 512 --subjects 8 44 18 --depths 3 4 5 6 --rr 16:3 16:4
                                                      # the class depths on other subjects (long hair, headwear)

Savings (each timed against the code path it replaces, same seed, same frame):
  aov-only    an AOV-only frame (RANA pretraining) built without the path integrator and the environment emitter,
              and without the triangles outside the view frustum; before: the full scene (emitter bitmap built
              and loaded, path integrator, every triangle) rendered by the AOV integrator. AOVs compared exactly.
  close-up    the same AOV-only frame through a camera that sees only the upper body (the frustum cull's case;
              the shipped protocols frame the whole body, so it culls nothing there).
  (textures)  a candidate measured but not adopted: every texture box-downsampled 2x (the mip level a 256-512 px
              person needs), AOV-only frame; albedo compared with the full-resolution textures.
  depth       the beauty pass at the scene class's depth (3) instead of the previous `standard` depth (4); every
              depth with the same seed, so depth d and depth 16 trace the same paths and differ only by the
              truncated bounces. Tolerance: the class's `tolerance_db` (rh_dataset/scenes/presets.json).
              `--only depth` runs this alone, for every --subjects (benchmark subjects in the scene's pose, light
              and camera fill: strand hair of other styles and colours, headwear) and every --depths.
  hidden      a full frame (beauty + every AOV) without the skin hidden under clothes; compared with the same
              frame rendered with every triangle, same seed (a path that never meets the hidden skin is traced
              identically), at the standard spp and at --check-spp.
  all         a standard full frame as the generator made it before (depth 4, every triangle) and now.
Times: median wall seconds of `render_frame` (scene load + passes) over --repeats runs, with and without alternated,
after a warm-up of each configuration (JIT kernels compiled and cached). Beauty differences: rh_eval's PSNR and FLIP in
display space over the evaluator's region, and relMSE over the person's box (bench_tradeoff.Scorer), the render
without the saving as the reference; "noise floor" is the standard preset's PSNR against a converged reference
(docs/TRADEOFFS.md), for scale.
"""
from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import bench_tradeoff as bt  # noqa: E402  (the fixed scenes and the scorer)

AOVS = ["mask", "albedo", "normal", "depth"]
ALL = ["image", *AOVS]
CLASS_OF = bt.SCENE_CLASS
PREVIOUS_STANDARD_DEPTH = 4  # rh_dataset/scenes/presets.json before scene classes
NOISE_FLOOR_DB = {"interior-apose": 45.0, "sunrise-random": 46.9}  # standard preset vs converged (TRADEOFFS.md)


def legacy_aov_only(scene, settings, seed: int):
    """An AOV-only frame as render_frame made it before: emitter bitmap built and loaded, the path integrator in
    the scene, every triangle; the AOV integrator renders it. Returns (layers, seconds)."""
    import mitsuba as mi

    from rh_dataset.lights import mitsuba_emitter_dict
    from rh_dataset.render.passes import _AOV_INTEGRATOR, _postprocess_aovs
    from rh_dataset.render.scene import scene_dict

    t = time.perf_counter()
    emitter = mitsuba_emitter_dict(scene.light)
    s = mi.load_dict(scene_dict(scene.meshes, emitter, scene.camera,
                                {"type": "path", "max_depth": settings.max_depth, "hide_emitters": False},
                                settings.spp, pixel_format="rgba"))
    aov = np.array(mi.render(s, integrator=mi.load_dict(_AOV_INTEGRATOR), spp=settings.aov_spp, seed=seed + 1),
                   dtype=np.float32)
    del s
    return _postprocess_aovs(aov, scene.camera, AOVS), time.perf_counter() - t


def new_aov_only(scene, settings, seed: int, hidden):
    from rh_dataset.render.passes import render_frame

    t = time.perf_counter()
    out = render_frame(scene.meshes, None, scene.camera, settings, AOVS, seed, hidden=hidden)
    return out, time.perf_counter() - t


def frame(scene, settings, layers, seed: int, hidden=None, emitter_from_light: bool = True):
    """render_frame as the generator calls it, the emitter dict built inside the timing (the generator builds it
    per frame). Returns (FrameRender, seconds)."""
    from rh_dataset.lights import mitsuba_emitter_dict
    from rh_dataset.render.passes import render_frame

    t = time.perf_counter()
    emitter = mitsuba_emitter_dict(scene.light) if emitter_from_light else scene.emitter
    out = render_frame(scene.meshes, emitter, scene.camera, settings, layers, seed, hidden=hidden)
    return out, time.perf_counter() - t


def timed_pair(fa, fb, repeats: int):
    """Run each once untimed (warm-up), then alternate; return (results_a, results_b, median_a, median_b)."""
    fa()
    fb()
    ta, tb, ra, rb = [], [], None, None
    for _ in range(repeats):
        ra, s = fa()
        ta.append(s)
        rb, s = fb()
        tb.append(s)
    return ra, rb, float(np.median(ta)), float(np.median(tb))


def aov_diff(a: dict, b: dict) -> dict:
    return {k: float(np.max(np.abs(a[k].astype(np.float64) - b[k]))) for k in AOVS if k in a and k in b}


def closeup_camera(scene):
    """A camera twice as close, aimed at the upper body: the legs and feet fall outside its frustum."""
    from rh_common.camera import Camera

    cam = scene.camera
    o, t = np.array(cam.origin), np.array(cam.target)
    lo, hi = scene.bounds
    target = t.copy()
    target[2] = lo[2] + 0.75 * (hi[2] - lo[2])
    origin = target + 0.45 * (o - t)
    return Camera(width=cam.width, height=cam.height, fov_y_deg=cam.fov_y_deg, origin=tuple(origin),
                  target=tuple(target))


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=list(bt.SCENES), choices=bt.SCENES,
                   help="bench_tradeoff.py's reference scenes (default: both)")
    p.add_argument("--resolution", type=int, default=256, help="frame width and height in pixels (default 256)")
    p.add_argument("--repeats", type=int, default=3,
                   help="timed runs with and without each saving, alternated after a warm-up; times are medians "
                        "(default 3; --only depth does not use it)")
    p.add_argument("--preset", default="standard", help="preset whose spp/aov_spp the frames use")
    p.add_argument("--check-spp", type=int, default=512,
                   help="also compare culled vs unculled beauty at this spp (0: skip)")
    p.add_argument("--deep", type=int, default=16, help="the deep reference depth of the depth check")
    p.add_argument("--out", default=None, help="write savings.json and savings.md here")
    p.add_argument("--only", choices=("all", "depth"), default="all", help="depth: the path-depth check alone")
    p.add_argument("--subjects", type=int, nargs="+", default=[0],
                   help="benchmark subjects (bench_tradeoff.build_scene)")
    p.add_argument("--depths", type=int, nargs="+", default=[2, 3, 4], help="depths compared with --deep")
    p.add_argument("--rr", nargs="*", default=[], help="--only depth: also max_depth:rr_depth configurations (Russian "
                   "roulette from rr_depth), e.g. 16:4")
    args = p.parse_args(argv)

    from rh_dataset.characters import build_character, sample_recipe
    from rh_dataset.generate import rng_for
    from rh_dataset.render.cull import HIDDEN_MARGIN_M, _hidden_faces
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import select_variant
    from rh_dataset.presets import load_presets, load_scene_classes
    from rh_eval.metrics import psnr

    variant = select_variant(None)
    pr = load_presets()[args.preset]
    classes = load_scene_classes()
    load0 = os.getloadavg()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average {load0[0]:.1f} {load0[1]:.1f} "
          f"{load0[2]:.1f}; Mitsuba {variant}; {args.resolution}x{args.resolution}; preset {pr.name} ({pr.spp} spp, "
          f"AOV {pr.aov_spp} spp); {args.repeats} repeats, medians", flush=True)
    results: dict = {"args": vars(args), "variant": variant, "load_before": load0, "scenes": {}}
    report: list[str] = []
    res = args.resolution
    if args.only == "depth":
        for subject in args.subjects:
            for name in args.scenes:
                depth_only(bt.build_scene(name, res, subject=subject), classes[CLASS_OF[name]], pr, args, results,
                           report)
        return _finish(args, results, report)
    character = build_character(sample_recipe(rng_for(0, "character", 0), pool="benchmark", index=0))
    t = time.perf_counter()
    hidden = {"body": _hidden_faces(character, HIDDEN_MARGIN_M)["body"]}  # uncached: timed
    t_hidden = time.perf_counter() - t
    print(f"hidden skin: {int(hidden['body'].sum())} of {len(hidden['body'])} body faces (margin "
          f"{HIDDEN_MARGIN_M * 100:.0f} cm), found in {t_hidden:.2f} s once per character", flush=True)
    results.update(hidden_faces=int(hidden["body"].sum()), hidden_seconds=t_hidden)
    for name in args.scenes:
        scene = bt.build_scene(name, res)
        scene.light = _light(name)
        from rh_dataset.characters import body_bounds

        scene.bounds = body_bounds(scene.meshes)
        cls = classes[CLASS_OF[name]]
        R: dict = {"scene_class": cls.name}
        results["scenes"][name] = R
        rows = []
        seed = 4242
        old = RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=PREVIOUS_STANDARD_DEPTH, cull=False)
        new = RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=cls.max_depth, cull=True)

        # -- AOV-only frames: first the light and the path integrator alone, then with the culling too
        nocull = dataclasses.replace(new, cull=False)
        b_lay, a_out, tb, ta = timed_pair(lambda: legacy_aov_only(scene, old, seed),
                                          lambda: new_aov_only(scene, nocull, seed, None), args.repeats)
        d = aov_diff(a_out.layers, b_lay)
        R["aov_only_no_light"] = {"before_s": tb, "after_s": ta, "max_abs_diff": d}
        rows.append(["AOV-only frame: no emitter, no path integrator (every triangle)", tb, ta, tb / ta,
                     "AOVs max abs diff " + ", ".join(f"{k} {v:.1e}" for k, v in d.items()), _culled(a_out.info)])
        b_lay, a_out, tb, ta = timed_pair(lambda: legacy_aov_only(scene, old, seed),
                                          lambda: new_aov_only(scene, new, seed, hidden), args.repeats)
        d = aov_diff(a_out.layers, b_lay)
        R["aov_only"] = {"before_s": tb, "after_s": ta, "max_abs_diff": d, "info": a_out.info}
        rows.append(["AOV-only frame: the above, and no hidden skin, no off-frustum triangles",
                     tb, ta, tb / ta, "AOVs max abs diff " + ", ".join(f"{k} {v:.1e}" for k, v in d.items()),
                     _culled(a_out.info)])

        # -- close-up AOV-only: the frustum cull's case
        close = copy.copy(scene)
        close.camera = closeup_camera(scene)
        b_lay, a_out, tb, ta = timed_pair(lambda: legacy_aov_only(close, old, seed),
                                          lambda: new_aov_only(close, new, seed, hidden), args.repeats)
        d = aov_diff(a_out.layers, b_lay)
        R["aov_only_closeup"] = {"before_s": tb, "after_s": ta, "max_abs_diff": d, "info": a_out.info}
        rows.append(["AOV-only frame, close-up camera (upper body)", tb, ta, tb / ta,
                     "AOVs max abs diff " + ", ".join(f"{k} {v:.1e}" for k, v in d.items()), _culled(a_out.info)])

        # -- a candidate not adopted: textures at half resolution (a coarser mip level) for the AOV-only frame
        half = copy.copy(scene)
        half.meshes = [_half_texture(m) for m in scene.meshes]
        f_lay, h_out, tf, th = timed_pair(lambda: new_aov_only(scene, new, seed, hidden),
                                          lambda: new_aov_only(half, new, seed, hidden), args.repeats)
        inside = f_lay.layers["mask"] > 0.5
        alb = psnr(h_out.layers["albedo"].astype(np.float64), f_lay.layers["albedo"].astype(np.float64),
                   data_range=1.0, mask=inside)
        R["half_textures"] = {"before_s": tf, "after_s": th, "albedo_psnr_vs_full": alb,
                              "load_before_s": f_lay.seconds["load"], "load_after_s": h_out.seconds["load"]}
        rows.append(["(not adopted) AOV-only frame with every texture box-downsampled 2x", tf, th, tf / th,
                     f"albedo PSNR {alb:.1f} dB vs full-resolution textures (inside the mask)", "-"])

        # -- path depth: the beauty pass only, same seed for every depth
        st = lambda depth: RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=depth, cull=False)  # noqa: E731
        deep, _ = frame(scene, st(args.deep), ["image", "mask"], seed)
        sc = bt.Scorer({"image": deep.layers["image"], "mask": deep.layers["mask"]}, scene.exposure)
        trunc = {}
        for depth in (2, 3, 4):
            img, _ = frame(scene, st(depth), ["image"], seed)
            trunc[depth] = sc.psnr(img.layers["image"])
        four, three, t4, t3 = timed_pair(lambda: frame(scene, st(PREVIOUS_STANDARD_DEPTH), ["image"], seed),
                                         lambda: frame(scene, st(cls.max_depth), ["image"], seed), args.repeats)
        e = sc.beauty(three.layers["image"])
        smallest = min((d_ for d_ in trunc if trunc[d_] >= cls.tolerance_db), default=None)
        R["depth"] = {"psnr_vs_deep": trunc, "tolerance_db": cls.tolerance_db, "smallest_within_tolerance": smallest,
                      "before_s": t4, "after_s": t3, "depth3_vs_deep": e}
        rows.append([f"beauty pass at the class depth {cls.max_depth} ({cls.name}; standard used "
                     f"{PREVIOUS_STANDARD_DEPTH})",
                     t4, t3, t4 / t3,
                     "PSNR vs depth %d, same seed: d2 %.1f, d3 %.1f, d4 %.1f dB (tolerance %.1f dB: smallest %s)"
                     % (args.deep, trunc[2], trunc[3], trunc[4], cls.tolerance_db, smallest), "-"])
        if args.check_spp:
            # The same-seed difference is the truncated bounces' mean (the bias) plus their Monte Carlo noise; more
            # samples shrink the noise only, so a rising PSNR shows the figure above is a conservative bound.
            hd = lambda depth: RenderSettings(spp=args.check_spp, aov_spp=1, max_depth=depth, cull=False)  # noqa
            deep_h, _ = frame(scene, hd(args.deep), ["image"], seed + 2)
            trunc_h = {}
            for depth in (2, 3):
                img, _ = frame(scene, hd(depth), ["image"], seed + 2)
                trunc_h[depth] = sc.psnr(img.layers["image"], reference=deep_h.layers["image"])
            R["depth_check"] = {"spp": args.check_spp, "psnr_vs_deep": trunc_h}
            rows.append([f"  the same at {args.check_spp} spp (not timed)", "-", "-", "-",
                         "PSNR vs depth %d, same seed: d2 %.1f, d3 %.1f dB" % (args.deep, trunc_h[2], trunc_h[3]),
                         "-"])

        # -- hidden skin: a full frame at the class depth, every triangle vs culled
        full_u = RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=cls.max_depth, cull=False)
        full_c = RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=cls.max_depth, cull=True)
        u, c, tu, tc = timed_pair(lambda: frame(scene, full_u, ALL, seed),
                                  lambda: frame(scene, full_c, ALL, seed, hidden), args.repeats)
        scu = bt.Scorer(u.layers, scene.exposure)
        e = scu.beauty(c.layers["image"])
        changed = int(np.count_nonzero(np.any(u.layers["image"] != c.layers["image"], axis=-1)))
        d = aov_diff(c.layers, u.layers)
        R["hidden"] = {"before_s": tu, "after_s": tc, "beauty_vs_unculled": e, "pixels_changed": changed,
                       "aov_max_abs_diff": d, "seconds_before": u.seconds, "seconds_after": c.seconds}
        rows.append([f"full frame without hidden skin ({pr.spp} spp)", tu, tc, tu / tc,
                     f"beauty PSNR {e['psnr']:.1f} dB, relMSE {e['relmse']:.1e}, FLIP {e['flip']:.1e}, {changed} px "
                     f"differ (noise floor {NOISE_FLOOR_DB[name]} dB); AOVs max abs diff "
                     + ", ".join(f"{k} {v:.1e}" for k, v in d.items()), _culled(c.info)])
        if args.check_spp:
            hs = lambda cull: RenderSettings(spp=args.check_spp, aov_spp=4, max_depth=cls.max_depth, cull=cull)  # noqa
            hu, _ = frame(scene, hs(False), ["image", "mask"], seed + 1)
            hc, _ = frame(scene, hs(True), ["image", "mask"], seed + 1, hidden)
            e = bt.Scorer(hu.layers, scene.exposure).beauty(hc.layers["image"])
            changed = int(np.count_nonzero(np.any(hu.layers["image"] != hc.layers["image"], axis=-1)))
            R["hidden_check"] = {"spp": args.check_spp, "beauty_vs_unculled": e, "pixels_changed": changed}
            rows.append([f"  the same at {args.check_spp} spp (beauty only, not timed)", "-", "-", "-",
                         f"beauty PSNR {e['psnr']:.1f} dB, relMSE {e['relmse']:.1e}, {changed} px differ", "-"])

        # -- everything together: the generator's standard frame before and now
        b_, a_, tb, ta = timed_pair(lambda: frame(scene, old, ALL, seed),
                                    lambda: frame(scene, new, ALL, seed, hidden), args.repeats)
        e = bt.Scorer(b_.layers, scene.exposure).beauty(a_.layers["image"])
        R["all"] = {"before_s": tb, "after_s": ta, "beauty_vs_before": e}
        rows.append([f"all: {pr.name} full frame, depth {PREVIOUS_STANDARD_DEPTH} + every triangle -> depth "
                     f"{cls.max_depth} + culled", tb, ta, tb / ta,
                     f"beauty PSNR {e['psnr']:.1f} dB vs before (same seed; noise floor {NOISE_FLOOR_DB[name]} dB)",
                     _culled(a_.info)])
        report.append(bt.table(f"{name} ({res}x{res}, class {cls.name}): time with and without each saving",
                               ["saving", "before s", "after s", "speed-up", "output difference", "left out"], rows))
    return _finish(args, results, report)


def depth_only(scene, cls, pr, args, results: dict, report: list) -> None:
    """The path-depth check alone on one scene, rendered as the preset renders (its sampler, env_spp and spp): each
    --depths, and each --rr max_depth:rr_depth (paths beyond rr_depth ended by Russian roulette, unbiased), against
    --deep with the same seed (for a plain depth: the truncated bounces' mean, the bias, plus their noise; for a
    roulette: its extra noise only, it has no bias beyond --deep's own truncation); the noise of each against a
    second seed (pair PSNR + 3.01 dB, as bench_sampler); and the beauty pass's process CPU seconds (the machine is
    shared: CPU seconds move less with its load than wall seconds)."""
    from rh_dataset.render.scene import RenderSettings

    seeds = (4242, 4243)
    layers = ["image", "mask"]

    def st(depth: int, rr: int | None = None) -> RenderSettings:
        return RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=depth, cull=False, sampler=pr.sampler,
                              env_spp=pr.env_spp, rr_depth=rr)

    def run(settings: RenderSettings, seed: int):
        c = time.process_time()
        out, _ = frame(scene, settings, layers, seed)
        return out, time.process_time() - c

    frame(scene, st(2), layers, 0)  # warm-up: kernels compile once (disk cache), not timed
    deep, cpu_deep = run(st(args.deep), seeds[0])
    sc = bt.Scorer({"image": deep.layers["image"], "mask": deep.layers["mask"]}, scene.exposure)
    configs = [(d, None) for d in args.depths] + [tuple(int(v) for v in c.split(":")) for c in args.rr]
    rows, R = [], {}
    for depth, rr in configs:
        a, cpu_a = run(st(depth, rr), seeds[0])
        b, cpu_b = run(st(depth, rr), seeds[1])
        vs_deep = sc.psnr(a.layers["image"])
        noise = sc.psnr(a.layers["image"], reference=b.layers["image"]) + 10 * math.log10(2.0)
        label = f"{depth}" if rr is None else f"{depth}, roulette from {rr}"
        R[label] = {"max_depth": depth, "rr_depth": rr, "psnr_vs_deep": vs_deep, "noise_psnr": noise,
                    "cpu_s": (cpu_a + cpu_b) / 2}
        rows.append([label, vs_deep, noise, (cpu_a + cpu_b) / 2])
    plain = {c[0]: R[f"{c[0]}"]["psnr_vs_deep"] for c in configs if c[1] is None}
    smallest = min((d for d in plain if plain[d] >= cls.tolerance_db), default=None)
    strands = sum(len(m.points) for m in scene.meshes if hasattr(m, "fibre"))
    key = f"{scene.name} subject {scene.subject}"
    results["scenes"][key] = {"scene_class": cls.name, "configs": R, "tolerance_db": cls.tolerance_db,
                              "smallest_within_tolerance": smallest, "strands": strands, "spp": pr.spp,
                              "deep": args.deep, "deep_cpu_s": cpu_deep}
    rows.append([f"{args.deep} (reference)", "-", "-", cpu_deep])
    report.append(bt.table(f"{key} ({strands} strands; {scene.camera.width}x{scene.camera.height}, {pr.name}: "
                           f"{pr.sampler} {pr.spp} spp, env {pr.env_spp}; class {cls.name}, tolerance "
                           f"{cls.tolerance_db} dB): smallest plain depth within it {smallest}",
                           ["max depth", f"PSNR dB vs depth {args.deep} (same seed)", "noise PSNR dB (pair)",
                            "beauty CPU s"], rows))


def _finish(args, results: dict, report: list) -> dict:
    load1 = os.getloadavg()
    results["load_after"] = load1
    print(f"\nload average after: {load1[0]:.1f} {load1[1]:.1f} {load1[2]:.1f}")
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "savings.json").write_text(json.dumps(results, indent=1, default=_jsonable))
        (out / "savings.md").write_text("\n".join(report) + "\n")
    return results


def _jsonable(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, float) and math.isinf(o):
        return "inf"
    return str(o)


def _half_texture(m):
    a = np.asarray(m.material.albedo, np.float32)
    H, W = a.shape[:2]
    a = a[:H // 2 * 2, :W // 2 * 2].reshape(H // 2, 2, W // 2, 2, 3).mean(axis=(1, 3))
    return dataclasses.replace(m, material=dataclasses.replace(m.material, albedo=a))


def _culled(info: dict) -> str:
    c = info["culled_faces"]
    return (f"{c['hidden_under_clothes']} hidden + {c['outside_frustum']} off-frustum faces"
            + ("" if info["emitter_loaded"] else "; no emitter"))


def _light(name: str):
    """The Light of a bench_tradeoff scene (its emitter dict is built per frame here, as the generator does)."""
    from rh_dataset.lights import LightSpec, build_light, bundled_hdris, load_hdri, normalised_scale

    lib = bundled_hdris()
    hdri = "interior" if name == "interior-apose" else "sunrise"
    base, _ = load_hdri(lib[hdri])
    rot = 0.0 if hdri == "interior" else bt._sun_rotation(base, -60.0)
    return build_light(LightSpec("envmap", hdri, str(lib[hdri]), rot, normalised_scale(base)))


if __name__ == "__main__":
    main()
