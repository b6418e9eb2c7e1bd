"""A peer, side by side in one run: our Mitsuba 3 pipeline against Blender Cycles (CPU, through bpy) on the same frame.

    python bench/bench_cycles.py                                   # both reference scenes, 256x256, 3 repeats
    python bench/bench_cycles.py --scenes interior-apose --max-spp 64 --repeats 1 --cycles-ref-spp 256   # quick

The frames are bench_tradeoff.py's reference scenes (a clothed character in A-pose under `interior`; the same
character in a random pose under the sun-heavy `sunrise`). Each is exported to one .npz (posed meshes with their
UVs, vertex normals and albedo textures; the camera's K and world_to_camera; the environment map and its rotation)
and rebuilt in Blender by bench/cycles_render_bpy.py, which renders it with Cycles on the CPU (2 threads, box pixel
filter one pixel wide, no denoiser, no adaptive sampling, no clamping, no glossy blur, MIS, linear float EXR).

Materials: the timed comparison uses the **Lambertian variant** of the frame on both sides (every part a diffuse
BSDF with its albedo texture, one-sided where ours is one-sided), where the physics is identical, so both renderers
should converge to the same image: Mitsuba at --ref-spp spp (same max depth) is the shared reference of the agreement
check. They do not quite: at the silhouettes of smooth-shaded cloth seen edge-on (shading and geometric normals
disagreeing) the two renderers shade a few pixels differently (measured 7 December 2026 on the draped dress: 0.5 % of
the person's pixels held 90 % of the converged difference, Cycles 2-3x brighter on one side of the dress and up to
10x darker on the other). That floor is a convention, not noise, so each renderer's sweep is scored against its own
converged render (--cycles-ref-spp on each side, each with its own sampler: Mitsuba's the standard preset's, every
pixel at full spp): the equal-error ratio compares how fast each one's noise falls, which is what the samplers and
the focusing decide. Each reference's own noise is left in (both QMC at the same count, so both curves flatten
alike); the Cycles errors against the shared Mitsuba reference are printed beside them.
The principled variant (Mitsuba `principled` vs Cycles' Principled BSDF) is rendered near convergence on both
sides and its systematic difference reported, not timed against a common reference (the two BSDF models differ).

Reported, per scene:
  agreement  converged Cycles (--cycles-ref-spp) vs the Mitsuba reference: relMSE and display-space PSNR over the
             evaluator's person region (bench_tradeoff.Scorer), per-channel mean radiance over the mask (ratio),
             the background (environment seen directly), the mask IoU (Cycles alpha vs Mitsuba coverage), the
             share of the person's pixels that holds 90 % of the difference, and, as the noise baseline, an
             independent Mitsuba render at the same spp against the same reference;
  sweep      spp 1..--max-spp for both renderers, render time only (Mitsuba: the beauty pass with the standard
             preset's sampler and focusing, plus the coverage pass focusing needs, scene load excluded; Cycles:
             first sample to 'Finished', scene sync/BVH excluded, both reported apart),
             median of --repeats, relMSE averaged over the repeats' independent seeds, each renderer against its
             own converged render (and Cycles also against Mitsuba's);
  ratio      the equal-error time ratio t_Mitsuba / t_Cycles at stated relMSE levels (default: the errors Mitsuba
             reaches at draft's spp, 64 and standard's spp, which the sweep includes), interpolated linearly in
             log(time)-log(relMSE) between the measured points ("not reached" where a sweep never gets there),
             and from power-law fits (spp >= 4);
  samples/s  pixels x spp / render time at the largest spp.
Machine shared with other jobs: read absolute seconds as +-30 %, ratios from one run as the figure.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:  # run as a script from anywhere
    sys.path.insert(0, str(HERE.parent))
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import bench_tradeoff as bt  # noqa: E402  (the reference scenes, the reference cache, the Scorer, the table printer)
from rh_common.blender import run_blender_script  # noqa: E402
from rh_common.imageio import atomic_path, read_exr, write_json  # noqa: E402
from rh_dataset.presets import load_presets  # noqa: E402

STANDARD = load_presets()["standard"]  # our side renders with the standard preset's sampler and focusing
PRESET_LEVEL_SPP = (load_presets()["draft"].spp, 64, STANDARD.spp)  # the equal-error levels' sample counts

BLENDER_SCRIPT = HERE / "cycles_render_bpy.py"
NEAR, FAR = 0.01, 1000.0  # rh_dataset.render.camera.mitsuba_sensor's clip planes


# ------------------------------------------------------------------------------------------------- export

def lambertian(meshes):
    """The Lambertian variant of posed meshes: same texture and sidedness, specular 0 (mitsuba_bsdf -> `diffuse`)."""
    return [dataclasses.replace(m, material=dataclasses.replace(m.material, specular=0.0)) for m in meshes]


def export_scene(path, meshes, env_radiance, env_rotation_deg: float, camera) -> Path:
    """Write one frame as a pickle-free .npz that cycles_render_bpy.py rebuilds (atomic)."""
    arrays = {
        "n_meshes": np.int64(len(meshes)),
        "width": np.int64(camera.width), "height": np.int64(camera.height),
        "K": np.asarray(camera.K, np.float64), "world_to_camera": np.asarray(camera.world_to_camera, np.float64),
        "near": np.float64(NEAR), "far": np.float64(FAR),
        "env_radiance": np.ascontiguousarray(env_radiance, dtype=np.float32),
        "env_rotation_deg": np.float64(env_rotation_deg),
    }
    for i, m in enumerate(meshes):
        p = f"mesh{i}_"
        arrays[p + "vertices"] = np.asarray(m.vertices, np.float32)
        arrays[p + "normals"] = np.asarray(m.normals, np.float32)
        arrays[p + "faces"] = np.asarray(m.faces, np.int32)
        arrays[p + "uvs"] = np.asarray(m.uvs, np.float32)  # v up, as Blender's
        arrays[p + "texture"] = np.asarray(m.material.albedo, np.float32)  # row 0 = top (v = 1)
        arrays[p + "material"] = np.array([m.material.roughness, m.material.specular,
                                           float(getattr(m.material, "two_sided", False))], np.float64)
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
    return path


# ------------------------------------------------------------------------------------------------- Cycles

def render_cycles(scene_npz, material: str, max_depth: int, renders: list[dict], *, threads: int = 2,
                  camera_check: bool = False, workdir=None, timeout: float = 7200.0) -> dict:
    """Render `renders` ([{spp, seed, mask?}]) of an exported scene with Cycles in one Blender process.

    Returns the Blender-side report with each render's `image` (H, W, 3) float32 linear radiance, or, for a mask
    render, `mask` (H, W) = alpha (coverage)."""
    with tempfile.TemporaryDirectory(dir=workdir) as d:
        d = Path(d)
        jobs = [{"spp": int(r["spp"]), "seed": int(r["seed"]), "mask": bool(r.get("mask", False)),
                 "out": str(d / f"r{k:03d}.exr")} for k, r in enumerate(renders)]
        job = {"scene": str(Path(scene_npz).resolve()), "material": material, "max_depth": int(max_depth),
               "threads": int(threads), "renders": jobs, "report": str(d / "report.json"),
               "camera_check": bool(camera_check)}
        write_json(d / "job.json", job)
        run_blender_script(BLENDER_SCRIPT, [d / "job.json"], timeout=timeout, threads=threads)
        rep = json.loads((d / "report.json").read_text())
        for r in rep["renders"]:
            px = read_exr(r["out"])
            if r.get("mask"):
                r["mask"] = np.clip(px[..., 3], 0.0, 1.0).astype(np.float32)
            else:
                r["image"] = np.ascontiguousarray(px[..., :3])
    return rep


# ------------------------------------------------------------------------------------------------- analysis

def equal_error_time(times, errors, level: float) -> float:
    """Time at which the (time, error) curve reaches `level`, interpolating log time linearly in log error between
    the two measured points that bracket it (NaN if the level is outside the measured range).

    Points are ordered by time; the error is made non-increasing first (a later, slower point can only do as well
    as the best before it is taken as "has reached"), so noisy ups and downs do not create several crossings."""
    t = np.asarray(times, float)
    e = np.asarray(errors, float)
    o = np.argsort(t)
    t, e = t[o], np.minimum.accumulate(e[o])
    if not (e[-1] <= level <= e[0]):
        return float("nan")
    lt, le = np.log(t), np.log(e)
    for k in range(len(t) - 1):
        if e[k] >= level >= e[k + 1]:
            if e[k] == e[k + 1]:
                return float(t[k])
            f = (math.log(level) - le[k]) / (le[k + 1] - le[k])
            return float(math.exp(lt[k] + f * (lt[k + 1] - lt[k])))
    return float(t[0])


def _finite(x: float) -> float | None:
    """x, or None where it is NaN (a level a sweep never reached): the JSON then says null, not an invalid NaN."""
    return None if math.isnan(x) else float(x)


def _or_unreached(x: float):
    """x for a table, or "not reached" where it is NaN."""
    return "not reached" if math.isnan(x) else x


def power_fit(times, errors) -> tuple[float, float]:
    """(a, s) of log error = a + s log time (least squares)."""
    s, a = np.polyfit(np.log(np.asarray(times, float)), np.log(np.asarray(errors, float)), 1)
    return float(a), float(s)


def fit_time(fit: tuple[float, float], level: float) -> float:
    a, s = fit
    return float(math.exp((math.log(level) - a) / s))


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    A, B = np.asarray(a) >= 0.5, np.asarray(b) >= 0.5
    union = np.count_nonzero(A | B)
    return float(np.count_nonzero(A & B) / union) if union else float("nan")


def agreement(img: np.ndarray, ref: np.ndarray, mask: np.ndarray, exposure: float = 1.0) -> dict:
    """Converged-vs-converged numbers on linear radiance: per-channel mean over the mask (ratio img/ref), relMSE over
    the mask and over the background (coverage 0: the environment seen directly), as bench_tradeoff defines relMSE
    (values at the frame's exposure, epsilon RELMSE_EPS)."""
    inside = mask >= 0.5
    bg = mask <= 1e-6
    x, r = img.astype(np.float64) * exposure, ref.astype(np.float64) * exposure
    m_img, m_ref = x[inside].mean(0), r[inside].mean(0)

    def per_pixel(sel):
        return np.mean((x[sel] - r[sel]) ** 2 / (r[sel] ** 2 + bt.RELMSE_EPS), axis=-1)

    e = np.sort(per_pixel(inside))[::-1]
    # The fewest pixels whose errors sum to 90 % of the total, as a share of the mask: about half for noise (0.47-0.48
    # measured for two Mitsuba renders on both scenes, 7 December), far less where a few pixels are shaded
    # differently (0.0047 for Cycles on the draped dress: a convention, not noise).
    k = int(np.searchsorted(np.cumsum(e), 0.9 * e.sum())) + 1 if e.sum() > 0 else 0
    return {"mean_ratio_rgb": (m_img / m_ref).tolist(), "relmse_mask": float(e.mean()),
            "share_for_90": k / max(len(e), 1),
            "relmse_background": float(per_pixel(bg).mean()) if bg.any() else None}


# ------------------------------------------------------------------------------------------------- main

def _mitsuba_render(scene, spp, depth, seed, args, chunk: int | None = None):
    """Our beauty image with the sampler and focusing of args (the `standard` preset's by default); the seconds are
    the beauty pass plus, when focused, the coverage pass it needs (in a dataset that pass is paid anyway). Rendered
    in calls of at most `chunk` spp (default --chunk-spp)."""
    lay, b, a, _ = bt.render(scene, ["image"], spp, depth, seed=seed, chunk=chunk or args.chunk_spp,
                             sampler=args.sampler, env_spp=args.env_spp, aov_spp=args.aov_spp)
    return lay["image"], b + a


def run_scene(name: str, args, work: Path) -> dict:
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings

    R: dict = {"scene": name}
    t = time.perf_counter()
    base = bt.build_scene(name, args.resolution, args.seed, strands=False)  # meshes only: see build_scene
    R["build_scene_s"] = time.perf_counter() - t  # our character/pose/light/camera, shared by both renderers
    diffuse = dataclasses.replace(base, name=f"{name}-lambertian", meshes=lambertian(base.meshes))
    R["triangles"] = base.triangles
    light = base.light
    npz = export_scene(work / f"{name}.npz", base.meshes, light.radiance, light.spec.rotation_deg, base.camera)
    depth = args.depth
    px = args.resolution ** 2

    # -- the converged reference: Mitsuba, Lambertian variant, same depth (bench_tradeoff's cache)
    ref_args = SimpleNamespace(cache=args.cache, ref_spp=args.ref_spp, ref_depth=depth, ref_aov_spp=args.ref_aov_spp,
                               chunk_spp=args.chunk_spp, seed=args.seed)
    ref, ref_s, cached = bt.reference(diffuse, ref_args, args.resolution)
    R["reference"] = {"renderer": "mitsuba", "spp": args.ref_spp, "depth": depth, "seconds": ref_s, "cached": cached}
    sc = bt.Scorer(ref, diffuse.exposure)
    print(f"\n## {name}: {base.triangles} triangles, reference {args.ref_spp} spp depth {depth} "
          f"({'cached' if cached else f'{ref_s:.0f} s'})", flush=True)

    # -- scene build cost on each side (reported apart from render time)
    st = RenderSettings(spp=1, aov_spp=1, max_depth=depth)
    render_frame(diffuse.meshes, diffuse.emitter, diffuse.camera, st, ["image"], 0)  # JIT warm-up
    fr = render_frame(diffuse.meshes, diffuse.emitter, diffuse.camera, st, ["image"], 1)
    R["mitsuba_load_s"] = fr.seconds["load"]

    # -- agreement at convergence (Lambertian): Cycles high spp + its mask, camera self-check
    cyc = render_cycles(npz, "diffuse", depth, [{"spp": args.cycles_ref_spp, "seed": 1},
                                                {"spp": 64, "seed": 2, "mask": True}],
                        threads=args.threads, camera_check=True, workdir=work)
    c_img = cyc["renders"][0]["image"]
    c_mask = cyc["renders"][1]["mask"]
    sc_cycles = bt.Scorer({"image": c_img, "mask": ref["mask"]}, diffuse.exposure)  # Cycles' own converged render
    # Mitsuba's own converged render at the same count, with its own sampler (a QMC one, as Cycles' Sobol) and every
    # pixel at full spp: the shared reference is `independent`, whose noise at 4096 spp is several times a
    # multijitter render's and would flatten our sweep's tail more than Cycles' (measured: 2.6e-4 -> 1.75e-4 from 256
    # to 528 spp on interior-apose against it, where the slope promised 1.1e-4).
    m_img, _ = _mitsuba_render(diffuse, args.cycles_ref_spp, depth, 424242,
                               SimpleNamespace(**{**vars(args), "env_spp": None}))
    sc_mitsuba = bt.Scorer({"image": m_img, "mask": ref["mask"]}, diffuse.exposure)
    ag_c = {**agreement(c_img, ref["image"], ref["mask"], diffuse.exposure), **sc.beauty(c_img)}
    ag_m = {**agreement(m_img, ref["image"], ref["mask"], diffuse.exposure), **sc.beauty(m_img)}
    R["agreement"] = {"spp": args.cycles_ref_spp, "cycles": ag_c, "mitsuba_same_spp": ag_m,
                      "mask_iou": mask_iou(c_mask, ref["mask"]),
                      "mask_mae": float(np.mean(np.abs(c_mask - ref["mask"]))),
                      "camera_max_px_error": cyc["camera_max_px_error"], "blender": cyc["blender"],
                      "cycles_build_s": cyc["build_s"], "cycles_sync_s": cyc["renders"][0]["sync_s"]}
    rows = [[f"Cycles {args.cycles_ref_spp} spp", ag_c["relmse"], ag_c["psnr"], ag_c["relmse_mask"],
             f"{100 * ag_c['share_for_90']:.2f} %", " / ".join(f"{v:.4f}" for v in ag_c["mean_ratio_rgb"]),
             ag_c["relmse_background"]],
            [f"Mitsuba {args.cycles_ref_spp} spp (noise baseline)", ag_m["relmse"], ag_m["psnr"], ag_m["relmse_mask"],
             f"{100 * ag_m['share_for_90']:.2f} %", " / ".join(f"{v:.4f}" for v in ag_m["mean_ratio_rgb"]),
             ag_m["relmse_background"]]]
    report = [bt.table(f"{name} (Lambertian): converged agreement vs Mitsuba {args.ref_spp} spp — mask IoU "
                       f"{R['agreement']['mask_iou']:.4f}, camera max reprojection error "
                       f"{R['agreement']['camera_max_px_error']:.2e} px",
                       ["render", "relMSE (person box)", "PSNR dB (person)", "relMSE (mask)",
                        "pixels holding 90 % of it (mask)", "mean radiance ratio R/G/B (mask)",
                        "relMSE (background)"], rows)]

    # -- principled: systematic difference of the two BSDF models (near convergence on both sides)
    if args.principled_spp:
        cp = render_cycles(npz, "principled", depth, [{"spp": args.principled_spp, "seed": 3}], threads=args.threads,
                           workdir=work)["renders"][0]["image"]
        mp, _ = _mitsuba_render(base, args.principled_spp * 4, depth, 515151, args)
        pr = agreement(cp, mp, ref["mask"], base.exposure)
        diff_ratio = agreement(ref["image"], mp, ref["mask"], base.exposure)["mean_ratio_rgb"]  # Lambertian / principled (Mitsuba)
        R["principled"] = {"cycles_spp": args.principled_spp, "mitsuba_spp": args.principled_spp * 4, **pr,
                           "mitsuba_lambertian_over_principled": diff_ratio}
        report.append(bt.table(
            f"{name} (principled): Cycles {args.principled_spp} spp vs Mitsuba {args.principled_spp * 4} spp",
            ["mean radiance ratio Cycles/Mitsuba R/G/B (mask)", "relMSE (mask)",
             "Mitsuba Lambertian/principled mean R/G/B"],
            [[" / ".join(f"{v:.4f}" for v in pr["mean_ratio_rgb"]), pr["relmse_mask"],
              " / ".join(f"{v:.4f}" for v in diff_ratio)]]))

    # -- the sweep (Lambertian): repeats interleaved so both renderers see the same load drift
    # Powers of 2, as the sampler takes them (multijitter renders 35 when asked for 32): both renderers at that count.
    from rh_dataset.render.sampler import taken_spp

    spps = sorted({taken_spp(args.sampler, 2 ** k) for k in range(0, 16) if 2 ** k <= args.max_spp} |
                  {s for s in PRESET_LEVEL_SPP if s <= args.max_spp and taken_spp(args.sampler, s) == s})
    m_t = {s: [] for s in spps}
    m_e = {s: [] for s in spps}
    c_t = {s: [] for s in spps}
    c_e = {s: [] for s in spps}
    c_x = {s: [] for s in spps}  # Cycles against the Mitsuba reference: noise plus the renderers' difference
    c_sync = []
    for rep in range(args.repeats):
        for s in spps:
            # One render call per count, as a dataset frame renders: the time of one call, and no chunk of a
            # count the sampler would not take (multijitter renders 528 for 512, which chunks of 256 split in 176s).
            img, sec = _mitsuba_render(diffuse, s, depth, 1000 * rep + s, args, chunk=s)
            m_t[s].append(sec)
            m_e[s].append(sc_mitsuba.beauty(img)["relmse"])
        # one Blender process per repeat: a 1-spp warm-up (kernels, caches), then the sweep
        cr = render_cycles(npz, "diffuse", depth, [{"spp": 1, "seed": 0}] +
                           [{"spp": s, "seed": 1000 * rep + s + 7} for s in spps], threads=args.threads, workdir=work)
        for r in cr["renders"][1:]:
            c_t[r["spp"]].append(r["render_s"])
            c_e[r["spp"]].append(sc_cycles.beauty(r["image"])["relmse"])
            c_x[r["spp"]].append(sc.beauty(r["image"])["relmse"])
            c_sync.append(r["sync_s"])
        R.setdefault("cycles_build_s", []).append(cr["build_s"])
        print(f"  repeat {rep + 1}/{args.repeats} done (load average {os.getloadavg()[0]:.1f})", flush=True)
    sweep = []
    for s in spps:
        sweep.append({"spp": s, "mitsuba_s": float(np.median(m_t[s])), "mitsuba_relmse": float(np.mean(m_e[s])),
                      "cycles_s": float(np.median(c_t[s])), "cycles_relmse": float(np.mean(c_e[s])),
                      "cycles_relmse_vs_mitsuba_ref": float(np.mean(c_x[s])),
                      "mitsuba_s_all": m_t[s], "cycles_s_all": c_t[s]})
    R["sweep"] = sweep
    R["cycles_sync_s_median"] = float(np.median(c_sync))
    top = sweep[-1]
    R["msamples_s"] = {"mitsuba": px * top["spp"] / top["mitsuba_s"] / 1e6,
                       "cycles": px * top["spp"] / top["cycles_s"] / 1e6, "at_spp": top["spp"]}
    R["relmse_vs_spp_slope"] = {"mitsuba": bt.fit_slope(spps, [r["mitsuba_relmse"] for r in sweep]),
                                "cycles": bt.fit_slope(spps, [r["cycles_relmse"] for r in sweep])}
    tail = [r for r in sweep if r["spp"] >= 4] or sweep
    fm = power_fit([r["mitsuba_s"] for r in tail], [r["mitsuba_relmse"] for r in tail])
    fc = power_fit([r["cycles_s"] for r in tail], [r["cycles_relmse"] for r in tail])
    R["fits"] = {"mitsuba": {"a": fm[0], "slope": fm[1]}, "cycles": {"a": fc[0], "slope": fc[1]}}
    rows = [[r["spp"], r["mitsuba_s"], px * r["spp"] / r["mitsuba_s"] / 1e6, r["mitsuba_relmse"],
             r["cycles_s"], px * r["spp"] / r["cycles_s"] / 1e6, r["cycles_relmse"],
             r["cycles_relmse_vs_mitsuba_ref"], r["mitsuba_s"] / r["cycles_s"]] for r in sweep]
    report.append(bt.table(
        f"{name} (Lambertian, depth {depth}, {args.repeats} repeats): render time (median) and relMSE (mean), "
        f"each against its own converged render (both {args.cycles_ref_spp} spp) — "
        f"relMSE~spp slope Mitsuba {R['relmse_vs_spp_slope']['mitsuba']:.3f}, "
        f"Cycles {R['relmse_vs_spp_slope']['cycles']:.3f}",
        ["spp", "Mitsuba s", "Mitsuba Msamples/s", "Mitsuba relMSE", "Cycles s", "Cycles Msamples/s",
         "Cycles relMSE", "Cycles relMSE vs Mitsuba's reference", "time ratio M/C (same spp)"], rows))

    # -- equal-error time ratio at stated levels
    levels = args.levels or _default_levels(sweep)
    eq, rows = [], []
    for lv in levels:
        tm = equal_error_time([r["mitsuba_s"] for r in sweep], [r["mitsuba_relmse"] for r in sweep], lv)
        tc = equal_error_time([r["cycles_s"] for r in sweep], [r["cycles_relmse"] for r in sweep], lv)
        tmf, tcf = fit_time(fm, lv), fit_time(fc, lv)
        eq.append({"relmse": lv, "mitsuba_s": _finite(tm), "cycles_s": _finite(tc), "ratio": _finite(tm / tc),
                   "mitsuba_fit_s": tmf, "cycles_fit_s": tcf, "ratio_fit": tmf / tcf})
        rows.append([lv, _or_unreached(tm), _or_unreached(tc), _or_unreached(tm / tc), tmf / tcf])
    R["equal_error"] = eq
    report.append(bt.table(f"{name}: equal-error time ratio Mitsuba/Cycles (< 1: Mitsuba faster)",
                           ["relMSE level", "Mitsuba s", "Cycles s", "ratio M/C (log-log interpolation)",
                            "ratio M/C (power-law fits, spp >= 4)"], rows))
    print(f"  samples/s at {top['spp']} spp: Mitsuba {R['msamples_s']['mitsuba']:.2f} M, Cycles "
          f"{R['msamples_s']['cycles']:.2f} M; scene build: ours {R['build_scene_s']:.1f} s (shared), Mitsuba load "
          f"{R['mitsuba_load_s']:.2f} s, Blender rebuild {np.median(R['cycles_build_s']):.2f} s + Cycles sync/BVH "
          f"{R['cycles_sync_s_median']:.2f} s per render", flush=True)
    R["report_md"] = report
    return R


def _default_levels(sweep) -> list[float]:
    """The relMSE our presets' sample counts reach on Mitsuba (`draft`'s, 64, `standard`'s; the sweep includes
    them), as measured: "the time each renderer needs for the error our presets accept". Falls back to the Mitsuba
    errors at the three largest spp of a shorter sweep."""
    by = {r["spp"]: r["mitsuba_relmse"] for r in sweep}
    spps = [s for s in PRESET_LEVEL_SPP if s in by] or sorted(by)[-3:]
    return [float(by[s]) for s in spps]


def _plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = results["scenes"]
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.6 * len(scenes), 4.4), squeeze=False)
    for ax, (name, R) in zip(axes[0], scenes.items()):
        sw = R["sweep"]
        for who, col, key in (("Mitsuba 3 (llvm_ad_rgb)", "tab:blue", "mitsuba"), ("Cycles (CPU)", "tab:red", "cycles")):
            t = [r[f"{key}_s"] for r in sw]
            e = [r[f"{key}_relmse"] for r in sw]
            ax.loglog(t, e, "o-", color=col, label=f"{who}, Msamples/s {R['msamples_s'][key]:.2f}")
            a, s = R["fits"][key]["a"], R["fits"][key]["slope"]
            tt = np.geomspace(min(t), max(t), 20)
            ax.loglog(tt, np.exp(a) * tt ** s, ":", color=col, lw=1, label=f"fit slope {s:.2f} (spp >= 4)")
            for r in sw:
                ax.annotate(str(r["spp"]), (r[f"{key}_s"], r[f"{key}_relmse"]), fontsize=6, color=col)
        for q in R["equal_error"]:
            ax.axhline(q["relmse"], color="grey", lw=0.5, alpha=0.6)
            label = "not reached" if q["ratio"] is None else f"{q['ratio']:.2f}"
            ax.annotate(f"M/C {label}", (ax.get_xlim()[0], q["relmse"]), fontsize=7, color="grey", va="bottom")
        ax.set_title(f"{name} (Lambertian)", fontsize=9)
        ax.set_xlabel("render time (s), scene build excluded")
        ax.set_ylabel(f"relMSE vs own converged render ({results['args']['cycles_ref_spp']} spp)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"Mitsuba vs Cycles, equal error ({results['args']['resolution']}^2, 2 threads each, "
                 f"load average {results['load_average_start']:.1f}; labels = spp)", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=list(bt.SCENES), choices=bt.SCENES,
                   help="bench_tradeoff.py's reference scenes compared (default: both)")
    p.add_argument("--resolution", type=int, default=256, help="frame width and height in pixels (default 256)")
    p.add_argument("--depth", type=int, default=4, help="Mitsuba max_depth on both sides (Cycles bounces = depth-2); "
                   "4 = the `standard` preset")
    p.add_argument("--ref-spp", type=int, default=4096, help="spp of the Mitsuba reference (cached in --cache)")
    p.add_argument("--ref-aov-spp", type=int, default=256, help="AOV spp of the reference (its mask sets the region)")
    p.add_argument("--cycles-ref-spp", type=int, default=4096,
                   help="spp of the converged Cycles render: the agreement check's, and the reference Cycles' sweep "
                        "is scored against (default 4096, as --ref-spp)")
    p.add_argument("--principled-spp", type=int, default=256, help="Cycles spp of the principled check (Mitsuba "
                   "uses 4x); 0 skips it")
    p.add_argument("--max-spp", type=int, default=256, help="largest spp of the sweep (powers of 2 from 1)")
    p.add_argument("--repeats", type=int, default=3,
                   help="rounds of the spp sweep, both renderers in each; times are medians over the rounds, "
                        "relMSE the mean of their independent seeds (default 3)")
    p.add_argument("--levels", type=float, nargs="*", default=None, help="relMSE levels for the equal-error ratio "
                   "(default: Mitsuba's relMSE at draft's spp, 64 and standard's spp, which the sweep includes)")
    p.add_argument("--threads", type=int, default=2, help="Cycles threads (Mitsuba's LLVM backend uses every core)")
    p.add_argument("--chunk-spp", type=int, default=256,
                   help="largest spp per Mitsuba render call; more is rendered in chunks and averaged (default 256)")
    p.add_argument("--sampler", default=STANDARD.sampler, help="Mitsuba's sampler for our renders (default: the "
                   f"standard preset's, {STANDARD.sampler})")
    p.add_argument("--env-spp", type=lambda v: None if v in ("", "none") else int(v), default=STANDARD.env_spp,
                   help="focused beauty pass: the environment seen directly at this spp, the person at full spp "
                        f"(default: the standard preset's, {STANDARD.env_spp}; 'none' renders every pixel at full spp)")
    p.add_argument("--aov-spp", type=int, default=STANDARD.aov_spp, help="spp of the coverage pass the focused pass "
                   f"needs (default: the standard preset's, {STANDARD.aov_spp})")
    p.add_argument("--cache", default="/tmp/rh_ref",
                   help="folder of the cached Mitsuba references, bench_tradeoff.py's (default /tmp/rh_ref)")
    p.add_argument("--out", default="/tmp/rh_cycles",
                   help="folder for cycles_peer.png, .md and .json, and a temporary folder of the scenes exported "
                        "to Blender (default /tmp/rh_cycles)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the scenes (their character and random pose, bench_tradeoff.build_scene); part of "
                        "the reference's cache key (default 0)")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    from rh_dataset.variant import select_variant

    variant = select_variant(None)
    load0 = os.getloadavg()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average {load0[0]:.2f} {load0[1]:.2f} "
          f"{load0[2]:.2f} (shared: times are noisy); Mitsuba {variant}; Cycles CPU {args.threads} threads; "
          f"{args.resolution}x{args.resolution}; depth {args.depth}; Mitsuba sampler {args.sampler}, env spp "
          f"{args.env_spp}, coverage pass {args.aov_spp} spp", flush=True)
    results = {"args": vars(args), "variant": variant, "load_average_start": load0[0],
               "load_average_start_all": list(load0), "scenes": {}}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=out) as work:
        for name in args.scenes:
            results["scenes"][name] = run_scene(name, args, Path(work))
    results["load_average_end"] = list(os.getloadavg())
    results["seconds"] = time.perf_counter() - t0
    md = [f"machine: {platform.machine()}, {os.cpu_count()} cores, load average at start {load0}, at end "
          f"{results['load_average_end']}; Mitsuba {variant}; {args.resolution}^2; depth {args.depth}"]
    for R in results["scenes"].values():
        md += R.pop("report_md")
    _plot(results, out / "cycles_peer.png")
    write_json(out / "cycles_peer.json", results)
    with atomic_path(out / "cycles_peer.md") as tmp:
        tmp.write_text("\n".join(md) + "\n")
    print(f"\nload average at end {results['load_average_end']}; {results['seconds']:.0f} s in all\n"
          f"plot: {out / 'cycles_peer.png'}; tables: {out / 'cycles_peer.md'}; data: {out / 'cycles_peer.json'}")
    return results


if __name__ == "__main__":
    main()
