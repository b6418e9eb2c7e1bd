"""Error vs render time on fixed reference scenes: spp, path depth, resolution, presets, denoising, AOV cost.

    python bench/bench_tradeoff.py                          # default: 256x256, reference 4096 spp depth 16 (cached)
    python bench/bench_tradeoff.py --max-spp 64 --ref-spp 256 --skip-presets   # quick look (~2 min)

Scenes (fixed; every choice below is deterministic):
  interior-apose   benchmark character 0 (seed 0) in anny's A-pose under the bundled `interior` HDRI;
  sunrise-random   the same character in the random test pose (seed 0, subject 0, test frame 0) under `sunrise`,
                   rotated so the sun (peak ~3e4 before normalisation) lights the body from the front-left.
Both lights are scaled to mean luminance 1 (`normalised_scale`), so the display exposure is 1.

A converged reference per scene (beauty: --ref-spp spp at --ref-depth; AOVs: --ref-aov-spp) is rendered once and
cached as .npz under --cache (default /tmp/rh_ref), keyed by every setting that changes it. High spp are rendered as
independent chunks of at most --chunk-spp spp with different seeds and averaged: with the box pixel filter this is
exactly the same estimator as one render at the total spp, and it keeps Mitsuba's wavefront (pixels x spp lanes)
within memory.

Errors, all against the reference of the same scene:
  relMSE   mean over the person's box of (x - r)^2 / (r^2 + 0.01), linear radiance at the frame's exposure, per
           channel (0.01 = (0.1)^2 keeps dark pixels from dominating; a common rendering convention);
  PSNR     rh-eval's image PSNR (`rh_eval.score_frame`, the reference as the ground truth): display space
           (srgb(clip(exposure * radiance))) over the evaluator's `default` region: the reference mask's bounding
           box dilated by round(50*min(H,W)/720) px, both images composited over white with the reference coverage;
  FLIP     rh-eval's image FLIP (LDR, ppd 67.02) on the same composited crop;
  AOVs     albedo PSNR (linear, inside the mask), normal mean angular error (rh_eval.metrics.normal_angular_error),
           mask mean absolute coverage error, each against the reference AOVs.
Times are wall-clock seconds of the beauty (or AOV) pass only, excluding scene loading; the machine is shared
(2 cores, other jobs running), so read them as +-20 % and prefer the ratios within one run.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SCENES = ("interior-apose", "sunrise-random")
SCENE_CLASS = {"interior-apose": "apose-envmap", "sunrise-random": "posed-envmap"}  # rh_dataset/scenes/presets.json
RELMSE_EPS = 0.01
DEPTH_TOLERANCE_DB = 50.0  # truncation error <= 1/10 of the 40 dB noise budget (in MSE)


# ------------------------------------------------------------------------------------------------- scenes

@dataclass
class Scene:
    name: str
    meshes: list
    emitter: dict
    camera: object
    exposure: float
    light_name: str
    pose_label: str
    triangles: int
    light: object = None  # the rh_dataset.lights.Light behind `emitter` (bench/bench_cycles.py re-creates it in Blender)
    subject: int = 0  # the benchmark subject index (build_scene)


def _sun_rotation(radiance: np.ndarray, target_phi_deg: float) -> float:
    """rotation_deg that puts the map's brightest pixel at world azimuth `target_phi_deg` (ARCHITECTURE.md mapping)."""
    from rh_common.colourspace import luminance

    H, W = radiance.shape[:2]
    j, i = np.unravel_index(int(np.argmax(luminance(radiance))), (H, W))
    phi_sun = math.degrees(2.0 * math.pi * (0.5 - (i + 0.5) / W))  # u = (0.5 - phi/2pi) W
    return float((target_phi_deg - phi_sun) % 360.0)


def build_scene(name: str, resolution: int, seed: int = 0, *, strands: bool = True, subject: int = 0) -> Scene:
    """One reference scene. strands=False leaves the hair strands out (a bald subject): bench_cycles.py compares
    renderers on triangle meshes only, since Cycles' curves are another primitive and BSDF than Mitsuba's.
    `subject`: the benchmark subject drawn (0 = the reference scenes'); pose, light and camera fill are those of the
    scene, so another subject (long hair, headwear) is the same light transport question on another body."""
    from rh_dataset.characters import body_bounds, build_character, pose_character, sample_recipe
    from rh_common.body_model import load_anny
    from rh_dataset.generate import exposure_for, rng_for
    from rh_dataset.lights import LightSpec, build_light, bundled_hdris, load_hdri, mitsuba_emitter_dict, normalised_scale
    from rh_dataset.poses import BodyPose, sample_pose
    from rh_common.camera import frame_body

    recipe = sample_recipe(rng_for(seed, "character", subject), pool="benchmark", index=subject)
    character = build_character(recipe)
    lib = bundled_hdris()
    if name == "interior-apose":
        pose, hdri, rot = BodyPose(bones={}, label="a-pose"), "interior", 0.0
    elif name == "sunrise-random":
        pose = sample_pose(rng_for(seed, "pose", 0, "test", 0), load_anny())
        hdri = "sunrise"
        base, _ = load_hdri(lib[hdri])
        rot = _sun_rotation(base, -60.0)  # the body faces -Y (azimuth -90 deg): sun front-left, 30 deg off axis
    else:
        raise ValueError(f"unknown scene {name!r}; known: {SCENES}")
    base, _ = load_hdri(lib[hdri])
    light = build_light(LightSpec("envmap", hdri, str(lib[hdri]), rot, normalised_scale(base)))
    meshes = pose_character(character, dict(pose.bones), pose.root_transform)
    if not strands:
        meshes = [m for m in meshes if hasattr(m, "faces")]
    lo, hi = body_bounds(meshes)
    cam = frame_body(lo, hi, resolution, resolution, 30.0, fill=0.9)
    return Scene(name, meshes, mitsuba_emitter_dict(light), cam, exposure_for(light), hdri, pose.label,
                 sum(len(m.faces) for m in meshes if hasattr(m, "faces")), light, subject)


# ------------------------------------------------------------------------------------------------- rendering

def render(scene: Scene, layers, spp: int, depth: int, seed: int, *, aov_spp: int = 1, chunk: int = 256,
           denoise: bool = False, sampler: str = "independent", env_spp: int | None = None):
    """render_frame in chunks of <= `chunk` spp (averaged); returns (layers, beauty_s, aov_s, denoise_s).

    env_spp: the focused beauty pass (the environment seen directly at env_spp, the person at spp); each chunk then
    runs its own coverage (AOV) pass at aov_spp first, whose seconds are added to aov_s."""
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings

    layers = list(layers)
    beauty_s = aov_s = den_s = 0.0
    acc: dict[str, np.ndarray] = {}
    # beauty in chunks
    if "image" in layers:
        n_chunks = -(-spp // chunk)
        per = [spp // n_chunks + (1 if k < spp % n_chunks else 0) for k in range(n_chunks)]
        for k, s in enumerate(per):
            focus = env_spp is not None and env_spp < s
            st = RenderSettings(spp=s, aov_spp=aov_spp, max_depth=depth, denoise=denoise and n_chunks == 1,
                                sampler=sampler, env_spp=env_spp if focus else None)
            lay = ["image"] + (["mask", "albedo", "normal"] if denoise and n_chunks == 1 else
                               ["mask"] if focus else [])
            out = render_frame(scene.meshes, scene.emitter, scene.camera, st, lay, seed + 7919 * k)
            beauty_s += out.seconds["beauty"]
            if focus:
                aov_s += out.seconds["aov"]
            den_s += out.seconds.get("denoise", 0.0)
            acc["image"] = acc.get("image", 0.0) + out.layers["image"] * (s / spp)
    aov_layers = [l for l in layers if l != "image"]
    if aov_layers:
        n_chunks = -(-aov_spp // chunk)
        per = [aov_spp // n_chunks + (1 if k < aov_spp % n_chunks else 0) for k in range(n_chunks)]
        sums: dict[str, np.ndarray] = {}
        for k, s in enumerate(per):
            st = RenderSettings(spp=1, aov_spp=s, max_depth=depth)
            out = render_frame(scene.meshes, scene.emitter, scene.camera, st, ["mask", "albedo", "normal", "depth"],
                               seed + 104729 * (k + 1))
            aov_s += out.seconds["aov"]
            cov = out.layers["mask"]
            w = s / aov_spp
            # average premultiplied quantities, then divide (matches one render at the total spp)
            sums["mask"] = sums.get("mask", 0.0) + w * cov
            sums["albedo"] = sums.get("albedo", 0.0) + w * out.layers["albedo"] * cov[..., None]
            sums["normal"] = sums.get("normal", 0.0) + w * out.layers["normal"] * cov[..., None]
            sums["depth"] = sums.get("depth", 0.0) + w * out.layers["depth"] * cov
        cov = sums["mask"]
        inside = cov > 1e-6
        safe = np.where(inside, cov, 1.0)
        acc["mask"] = cov.astype(np.float32)
        acc["albedo"] = np.where(inside[..., None], sums["albedo"] / safe[..., None], 0.0).astype(np.float32)
        n = sums["normal"]
        ln = np.linalg.norm(n, axis=-1, keepdims=True)
        acc["normal"] = np.where(inside[..., None] & (ln > 1e-8), n / np.maximum(ln, 1e-8), 0.0).astype(np.float32)
        acc["depth"] = np.where(inside, sums["depth"] / safe, 0.0).astype(np.float32)
    return {k: acc[k] for k in layers if k in acc}, beauty_s, aov_s, den_s


def _cache_key(scene: Scene, args, res: int) -> str:
    import mitsuba

    from rh_dataset import __version__

    d = {"scene": scene.name, "res": res, "spp": args.ref_spp, "depth": args.ref_depth, "aov_spp": args.ref_aov_spp,
         "chunk": args.chunk_spp, "seed": args.seed, "rh": __version__, "mitsuba": mitsuba.__version__,
         "tris": scene.triangles, "v": 1}
    if scene.subject:
        d["subject"] = scene.subject
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def reference(scene: Scene, args, res: int) -> tuple[dict, float, bool]:
    """The cached converged reference (image, mask, albedo, normal, depth); (layers, render seconds, from_cache)."""
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / f"{scene.name}_{res}_{_cache_key(scene, args, res)}.npz"
    if path.is_file():
        with np.load(path) as z:
            return {k: z[k] for k in z.files if k != "seconds"}, float(z["seconds"]), True
    lay, b, a, _ = render(scene, ["image", "mask", "albedo", "normal", "depth"], args.ref_spp, args.ref_depth,
                          seed=10_000_000, aov_spp=args.ref_aov_spp, chunk=args.chunk_spp)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, seconds=np.float64(b + a), **lay)
    os.replace(tmp, path)
    return lay, b + a, False


# ------------------------------------------------------------------------------------------------- metrics

class Scorer:
    """Errors of a beauty image / AOVs against one scene's reference (see the module docstring). PSNR and FLIP are
    rh-eval's, from `rh_eval.score_frame` with the reference as the ground truth."""

    def __init__(self, ref: dict, exposure: float):
        from rh_common.colourspace import quantize8
        from rh_eval import FrameGroundTruth
        from rh_eval.conventions import Convention, compute_region

        self.ref = ref
        self.exposure = exposure
        self.conv = Convention()  # the evaluator's default region: dilated mask bbox, over white
        self.truth = FrameGroundTruth(mask=quantize8(ref["mask"]), exposure=exposure, image=ref["image"])
        self.region = compute_region(self.truth.mask, self.conv)
        self.inside = ref["mask"] >= 0.5
        r = self.region
        self.ref_lin = ref["image"][r.y0:r.y1, r.x0:r.x1].astype(np.float64) * exposure

    def _scores(self, img: np.ndarray, metrics, reference: np.ndarray | None = None):
        from rh_eval import FramePrediction, score_frame

        truth = self.truth if reference is None else dataclasses.replace(self.truth, image=reference)
        return score_frame(FramePrediction(image=img), truth, self.conv, metrics).image

    def psnr(self, img: np.ndarray, reference: np.ndarray | None = None) -> float:
        """rh-eval's PSNR of `img` against the reference (or against `reference`, in the reference's region)."""
        return self._scores(img, ("psnr",), reference).psnr

    def beauty(self, img: np.ndarray) -> dict:
        r = self.region
        x = img[r.y0:r.y1, r.x0:r.x1].astype(np.float64) * self.exposure
        rel = float(np.mean((x - self.ref_lin) ** 2 / (self.ref_lin ** 2 + RELMSE_EPS)))
        e = self._scores(img, ("psnr", "flip"))
        return {"relmse": rel, "psnr": e.psnr, "flip": e.flip}

    def aovs(self, lay: dict) -> dict:
        from rh_eval.metrics import normal_angular_error, psnr

        m = self.inside
        return {
            "albedo_psnr": psnr(np.clip(lay["albedo"], 0, 1).astype(np.float64),
                                self.ref["albedo"].astype(np.float64), data_range=1.0, mask=m),
            "normal_deg": normal_angular_error(lay["normal"].astype(np.float64),
                                               self.ref["normal"].astype(np.float64), mask=m),
            "mask_mae": float(np.mean(np.abs(lay["mask"] - self.ref["mask"]))),
        }


def _box_down(img: np.ndarray, f: int) -> np.ndarray:
    if f == 1:
        return img
    H, W = img.shape[:2]
    return img.reshape(H // f, f, W // f, f, *img.shape[2:]).mean(axis=(1, 3))


# ------------------------------------------------------------------------------------------------- report

def table(title: str, header: list[str], rows: list[list]) -> str:
    def fmt(v):
        if isinstance(v, float):
            if math.isinf(v):
                return "inf"
            if v != 0 and (abs(v) < 1e-3 or abs(v) >= 1e5):
                return f"{v:.2e}"
            return f"{v:.4g}"
        return str(v)

    lines = [f"\n### {title}\n", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]
    text = "\n".join(lines)
    print(text, flush=True)
    return text


def fit_slope(x, y) -> float:
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    return float(np.polyfit(lx, ly, 1)[0])


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cache", default="/tmp/rh_ref", help="folder for cached references (default /tmp/rh_ref)")
    p.add_argument("--out", default=None, help="folder for the plot and results JSON (default: --cache)")
    p.add_argument("--scenes", nargs="+", default=list(SCENES), choices=SCENES,
                   help="reference scenes measured (default: both)")
    p.add_argument("--resolution", type=int, default=256,
                   help="frame width and height in pixels, of the references and every sweep but the resolution "
                        "sweep (default 256)")
    p.add_argument("--ref-spp", type=int, default=4096, help="spp of the references' beauty pass (default 4096)")
    p.add_argument("--ref-depth", type=int, default=16,
                   help="max path depth of the references' beauty pass (default 16)")
    p.add_argument("--ref-aov-spp", type=int, default=1024,
                   help="spp of the references' AOV pass: mask, albedo, normal, depth (default 1024)")
    p.add_argument("--chunk-spp", type=int, default=256, help="largest spp per Mitsuba render call")
    p.add_argument("--max-spp", type=int, default=1024, help="largest spp of the sweep (powers of 2 from 1)")
    p.add_argument("--sweep-depth", type=int, default=12, help="max depth used for the spp sweep")
    p.add_argument("--depths", type=int, nargs="+", default=[2, 3, 4, 5, 6, 8, 10, 12, 16],
                   help="max depths of the depth sweep, each at --depth-spp with the same seed; the deepest is "
                        "what the others' truncation is measured against")
    p.add_argument("--depth-spp", type=int, default=64, help="spp of the depth sweep")
    p.add_argument("--resolutions", type=int, nargs="+", default=[128, 256, 512],
                   help="frame sizes in pixels of the resolution sweep, at --res-spp; a multiple of --resolution is "
                        "also box-downsampled to it and scored against the reference")
    p.add_argument("--res-spp", type=int, default=16, help="spp of the resolution sweep (default 16)")
    p.add_argument("--denoise-spp", type=int, nargs="+", default=[1, 4, 16, 64, 256],
                   help="spp of the denoised renders (pyoidn, albedo and normal guides); those above --chunk-spp "
                        "are skipped")
    p.add_argument("--max-aov-spp", type=int, default=64,
                   help="largest AOV spp of the AOV sweep (powers of 2 from 1; default 64)")
    p.add_argument("--skip-presets", action="store_true",
                   help="leave out the table of each render preset against the reference")
    p.add_argument("--skip-aov-only", action="store_true",
                   help="leave out the timing of an AOV-only frame against a full frame (draft and standard)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the scenes (their character and random pose); part of the references' cache key "
                        "(default 0)")
    args = p.parse_args(argv)
    out_dir = Path(args.out or args.cache)
    out_dir.mkdir(parents=True, exist_ok=True)

    from rh_dataset.variant import select_variant
    from rh_dataset.presets import load_presets

    variant = select_variant(None)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.1f} (shared: times are noisy); Mitsuba {variant}; {args.resolution}x{args.resolution}; "
          f"reference {args.ref_spp} spp depth {args.ref_depth}, AOVs {args.ref_aov_spp} spp", flush=True)
    results: dict = {"args": vars(args), "variant": variant, "scenes": {}}
    report: list[str] = []
    res = args.resolution
    px = res * res
    spps = [2 ** k for k in range(0, 11) if 2 ** k <= args.max_spp]
    for name in args.scenes:
        t0 = time.perf_counter()
        scene = build_scene(name, res, args.seed)
        R: dict = {"triangles": scene.triangles, "light": scene.light_name, "pose": scene.pose_label}
        results["scenes"][name] = R
        # warm-up (JIT compile, cached on disk afterwards): not timed
        render(scene, ["image", "mask", "albedo", "normal", "depth"], 1, args.sweep_depth, seed=0, aov_spp=1)
        ref, ref_s, cached = reference(scene, args, res)
        sc = Scorer(ref, scene.exposure)
        cover = float(ref["mask"].mean())
        R.update(coverage=cover, reference_seconds=ref_s, reference_cached=cached)
        print(f"\n## {name}: {scene.triangles} triangles, light {scene.light_name}, pose {scene.pose_label}, "
              f"person covers {cover:.0%}; reference {'from cache' if cached else 'rendered'} "
              f"({ref_s:.0f} s render time); region {sc.region.shape}", flush=True)

        # -- spp sweep
        rows, sweep = [], []
        for spp in spps:
            lay, b, _, _ = render(scene, ["image"], spp, args.sweep_depth, seed=1000 + spp, chunk=args.chunk_spp)
            e = sc.beauty(lay["image"])
            from rh_dataset.render.passes import count_fireflies

            ff = count_fireflies(lay["image"])
            sweep.append({"spp": spp, "seconds": b, **e, "fireflies": ff})
            rows.append([spp, b, px * spp / b / 1e6, e["relmse"], e["psnr"], e["flip"], ff])
        slope = fit_slope([r["spp"] for r in sweep], [r["relmse"] for r in sweep])
        tail = [r for r in sweep if r["spp"] >= 4]
        slope_tail = fit_slope([r["spp"] for r in tail], [r["relmse"] for r in tail]) if len(tail) >= 2 else float("nan")
        R["spp_sweep"], R["relmse_slope"], R["relmse_slope_spp_ge_4"] = sweep, slope, slope_tail
        report.append(table(f"{name}: spp sweep (depth {args.sweep_depth}) — fitted slope of log relMSE vs log spp "
                            f"{slope:.3f} (all), {slope_tail:.3f} (spp >= 4)",
                            ["spp", "beauty s", "Msamples/s", "relMSE", "PSNR dB", "FLIP", "fireflies"], rows))

        # -- depth sweep: same seed for every depth, so depth d and the deepest differ only by the truncated paths
        rows, dsweep = [], []
        deep = max(args.depths)
        imgs = {}
        for d in sorted(args.depths):
            render(scene, ["image"], 1, d, seed=0)  # warm-up: each max depth is its own kernel
            lay, b, _, _ = render(scene, ["image"], args.depth_spp, d, seed=777, chunk=args.chunk_spp)
            imgs[d] = (lay["image"], b)
        lum = lambda im: float((im[..., :3] @ np.array([0.2126, 0.7152, 0.0722]))[sc.inside].mean())  # noqa: E731
        smallest = None
        for d in sorted(args.depths):
            img, b = imgs[d]
            e = sc.beauty(img)
            trunc_db = sc.psnr(img, reference=imgs[deep][0])
            missing = 1.0 - lum(img) / lum(imgs[deep][0])
            if smallest is None and trunc_db >= DEPTH_TOLERANCE_DB:
                smallest = d
            dsweep.append({"depth": d, "seconds": b, **e, "truncation_psnr": trunc_db, "missing_energy": missing})
            rows.append([d, b, e["relmse"], e["psnr"], trunc_db, f"{100 * missing:.3f} %"])
        R["depth_sweep"], R["smallest_depth"] = dsweep, smallest
        report.append(table(
            f"{name}: max depth sweep at {args.depth_spp} spp (same seed) — smallest depth whose display-space "
            f"PSNR vs depth {deep} (same samples) >= {DEPTH_TOLERANCE_DB:.0f} dB: {smallest}",
            ["max depth", "beauty s", "relMSE vs ref", "PSNR vs ref dB", f"PSNR vs depth {deep}, same seed",
             "energy missing (person)"], rows))

        # -- resolution: time, and error after box-downsampling to the reference grid (box filter: exact)
        rows, rsweep = [], []
        for r_ in args.resolutions:
            s_r = build_scene(name, r_, args.seed)
            render(s_r, ["image"], 1, args.sweep_depth, seed=0)  # warm-up at this size
            lay, b, _, _ = render(s_r, ["image"], args.res_spp, args.sweep_depth, seed=55, chunk=args.chunk_spp)
            row = {"resolution": r_, "spp": args.res_spp, "seconds": b, "msamples_s": r_ * r_ * args.res_spp / b / 1e6}
            if r_ >= res and r_ % res == 0:
                e = sc.beauty(_box_down(lay["image"], r_ // res))
                row.update(e)
                row["compared_at"] = res
            rsweep.append(row)
            rows.append([r_, args.res_spp, b, row["msamples_s"], row.get("relmse", "-"), row.get("psnr", "-"),
                         f"at {res} (box {r_ // res}x)" if "relmse" in row else "-"])
        R["resolution_sweep"] = rsweep
        report.append(table(f"{name}: resolution at {args.res_spp} spp (depth {args.sweep_depth})",
                            ["resolution", "spp", "beauty s", "Msamples/s", "relMSE", "PSNR dB", "compared"], rows))

        # -- AOVs vs their reference
        rows, asweep = [], []
        for a in [2 ** k for k in range(0, 11) if 2 ** k <= args.max_aov_spp]:
            lay, _, a_s, _ = render(scene, ["mask", "albedo", "normal"], 1, 2, seed=3000 + a, aov_spp=a,
                                    chunk=args.chunk_spp)
            e = sc.aovs(lay)
            asweep.append({"aov_spp": a, "seconds": a_s, **e})
            rows.append([a, a_s, px * a / a_s / 1e6, e["albedo_psnr"], e["normal_deg"], e["mask_mae"]])
        R["aov_sweep"] = asweep
        report.append(table(f"{name}: AOV pass vs reference AOVs ({args.ref_aov_spp} spp)",
                            ["aov spp", "aov s", "Msamples/s", "albedo PSNR dB (mask)", "normal err deg (mask)",
                             "mask MAE"], rows))

        # -- presets: noise floor of each preset's beauty image vs the converged reference
        if not args.skip_presets:
            rows, psweep = [], []
            for pname, pr in load_presets().items():
                pr = dataclasses.replace(pr, max_depth=pr.depth_for(SCENE_CLASS[name]))
                lay, b, _, _ = render(scene, ["image"], pr.spp, pr.max_depth, seed=5000 + pr.spp, chunk=args.chunk_spp,
                                      sampler=pr.sampler)
                e = sc.beauty(lay["image"])
                # the reference's own variance inflates a measured MSE by (1 + spp/ref_spp) (unbiased noise)
                corr = e["psnr"] + 10 * math.log10(1 + pr.spp / args.ref_spp)
                psweep.append({"preset": pname, "sampler": pr.sampler, "spp": pr.spp, "max_depth": pr.max_depth, "seconds": b, **e,
                               "psnr_ref_noise_corrected": corr})
                rows.append([pname, pr.sampler, pr.spp, pr.max_depth, b, e["relmse"], e["psnr"], corr, e["flip"]])
            R["presets"] = psweep
            report.append(table(f"{name}: presets vs converged reference ({args.ref_spp} spp, depth {args.ref_depth})",
                                ["preset", "sampler", "spp", "max depth", "beauty s", "relMSE", "PSNR dB",
                                 "PSNR dB (ref noise removed)", "FLIP"], rows))

        # -- denoising (pyoidn, HDR, albedo+normal guides from the frame's own AOV pass at aov_spp 16)
        rows, dn = [], []
        for spp in [s for s in args.denoise_spp if s <= args.chunk_spp]:
            lay, b, a_s, den = render(scene, ["image"], spp, args.sweep_depth, seed=9000 + spp, aov_spp=16,
                                      chunk=args.chunk_spp, denoise=True)
            e = sc.beauty(lay["image"])
            noisy = next((r for r in sweep if r["spp"] == spp), None)
            dn.append({"spp": spp, "seconds": b, "aov_seconds": a_s, "denoise_seconds": den, **e})
            ref_lum = float((ref["image"] @ np.array([0.2126, 0.7152, 0.0722]))[sc.inside].mean())
            den_lum = float((lay["image"] @ np.array([0.2126, 0.7152, 0.0722]))[sc.inside].mean())
            dn[-1]["mean_bias"] = den_lum / ref_lum - 1
            rows.append([spp, b + a_s + den, den, e["relmse"], e["psnr"], e["flip"],
                         noisy["psnr"] if noisy else "-", f"{100 * (den_lum / ref_lum - 1):+.2f} %"])
        R["denoise"] = dn
        report.append(table(f"{name}: pyoidn denoising (albedo+normal guides, AOV pass 16 spp)",
                            ["spp", "total s (beauty+aov+denoise)", "denoise s", "relMSE", "PSNR dB", "FLIP",
                             "PSNR dB without denoising", "mean luminance bias (person)"], rows))

        # -- AOV-only frame vs full frame (what pretraining data costs)
        if not args.skip_aov_only:
            from rh_dataset.render.passes import render_frame
            from rh_dataset.render.scene import RenderSettings

            rows, ao = [], []
            for pname in ("draft", "standard"):
                pr = load_presets()[pname]
                st = RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=pr.depth_for(SCENE_CLASS[name]),
                                    sampler=pr.sampler, env_spp=pr.env_spp)
                t = time.perf_counter()
                render_frame(scene.meshes, scene.emitter, scene.camera, st, ["mask", "albedo", "normal", "depth"], 1)
                t_aov = time.perf_counter() - t
                t = time.perf_counter()
                render_frame(scene.meshes, scene.emitter, scene.camera, st,
                             ["image", "mask", "albedo", "normal", "depth"], 1)
                t_full = time.perf_counter() - t
                ao.append({"preset": pname, "aov_only_s": t_aov, "full_s": t_full})
                rows.append([pname, t_aov, t_full, t_full / t_aov])
            R["aov_only"] = ao
            report.append(table(f"{name}: AOV-only frame vs full frame (render_frame wall time incl. scene load)",
                                ["preset", "AOV-only s", "full s", "ratio"], rows))
        R["bench_seconds"] = time.perf_counter() - t0

    _plot(results, out_dir / "tradeoff.png")
    (out_dir / "tradeoff.json").write_text(json.dumps(results, indent=1, default=float))
    (out_dir / "tradeoff.md").write_text("\n".join(report) + "\n")
    print(f"\nplot: {out_dir / 'tradeoff.png'}; tables: {out_dir / 'tradeoff.md'}; data: {out_dir / 'tradeoff.json'}")
    return results


def _plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, R in results["scenes"].items():
        sw = R["spp_sweep"]
        t = [r["seconds"] for r in sw]
        line, = axes[0].loglog(t, [r["relmse"] for r in sw], "o-", label=f"{name} (slope vs spp {R['relmse_slope']:.2f})")
        if R.get("denoise"):
            axes[0].loglog([r["seconds"] + r["aov_seconds"] + r["denoise_seconds"] for r in R["denoise"]],
                           [r["relmse"] for r in R["denoise"]], "s--", color=line.get_color(), label=f"{name} denoised")
        axes[1].semilogx(t, [r["flip"] for r in sw], "o-", color=line.get_color(), label=name)
        if R.get("denoise"):
            axes[1].semilogx([r["seconds"] + r["aov_seconds"] + r["denoise_seconds"] for r in R["denoise"]],
                             [r["flip"] for r in R["denoise"]], "s--", color=line.get_color())
        for r in sw:
            axes[0].annotate(str(r["spp"]), (r["seconds"], r["relmse"]), fontsize=6)
    axes[0].set_xlabel("render time (s)")
    axes[0].set_ylabel("relMSE vs reference (person box)")
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel("render time (s)")
    axes[1].set_ylabel("FLIP vs reference (display space)")
    axes[0].grid(True, which="both", alpha=0.3)
    axes[1].grid(True, which="both", alpha=0.3)
    fig.suptitle(f"error vs time ({results['args']['resolution']}^2, shared 2-core machine; labels = spp)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    main()
