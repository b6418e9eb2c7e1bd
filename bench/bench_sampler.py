"""Which Mitsuba sampler: error vs samples per pixel of each, at the counts it really takes, and each preset's floor.

    python bench/bench_sampler.py                                   # sweep at 128x128 + floors at 512x512
    python bench/bench_sampler.py --resolution 256 --ref-chunks 128 --skip-floor
    python bench/bench_sampler.py --skip-sweep --floor standard:multijitter:48 standard:independent:128
    python bench/bench_sampler.py --skip-sweep --floor standard:multijitter:99:4 \
        standard:multijitter:99:4:a16-36-64-100-169-256

In: the two reference scenes of bench/bench_tradeoff.py (interior-apose, sunrise-random), each at the path depth of
its scene class (rh_dataset/scenes/presets.json: what the presets render). Out: printed tables (and --out JSON).

Sweep. Each of Mitsuba's samplers (independent, stratified, multijitter, orthogonal, ldsampler) renders the beauty
pass at the sample counts it takes nearest to --targets (`rh_dataset.render.sampler.taken_spp`: stratified rounds
to a square, orthogonal to a prime squared, ldsampler to a power of 4), at --seeds seeds, through `render_frame`.
Error: relMSE = mean over the person's box (the evaluator's dilated mask box) of (x - r)^2 / (r^2 + 0.01), exposure-
scaled linear radiance, per channel; the fit is log relMSE = c + s log spp (least squares over the counts, mean of
the seeds), reported as slope s and constant 10^c (the relMSE one sample would have on that line).

Reference. --ref-chunks renders of --ref-chunk-spp spp each with `ldsampler` (randomised QMC: a fresh seed is an
independent scramble, each chunk an unbiased estimate) are averaged. Its remaining variance is estimated per pixel
from the spread of the chunks (var of the mean = var of chunks / K) and subtracted from each measured relMSE
(E[(x - r)^2] = MSE(x) + Var(r) for x independent of r): the "ref floor" column shows how small it is next to the
errors. A QMC reference could hide a bias that every chunk shares, so an `independent` reference (--check-chunks
chunks) is rendered too and the two are compared: mean over the box of (r_ld - r_ind)^2, over the mean of
var_ld + var_ind, is ~1 when both estimate the same image and >> 1 if one is biased.

Floors. Each --floor preset:sampler:spp[:env_spp] renders the beauty pass at 512x512 (--floor-resolution) twice with
independent seeds; for two independent unbiased renders E|x1 - x2|^2 = 2 MSE(x), so the PSNR against a converged
reference is PSNR(x1 vs x2) + 3.01 dB (display space, rh-eval's PSNR over the evaluator's default region, exactly
what bench_tradeoff's presets table reports). The sweep run checks this estimate against its deep reference at the
sweep resolution ("pair est." next to "vs ref" in the table). Times: wall seconds of the beauty pass only; the
machine is shared, so compare the ratios within one run.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

SAMPLER_NAMES = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")
RELMSE_EPS = 0.01


def _render(scene, sampler: str, spp: int, depth: int, seed: int, layers=("image",), aov_spp: int = 4,
            env_spp: int | None = None, tiers: tuple[int, ...] | None = None, cpu: bool = False,
            rr: int | None = None):
    """render_frame's layers and the beauty pass's wall seconds (with `cpu`: also the frame's process CPU seconds,
    which move less with the shared machine's load than wall seconds; the AOV pass is in them)."""
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings

    st = RenderSettings(spp=spp, aov_spp=aov_spp, max_depth=depth, sampler=sampler, env_spp=env_spp,
                        adaptive_tiers=tiers, rr_depth=rr)
    if env_spp is not None:
        layers = tuple(layers) + ("mask",)  # the focused beauty pass takes its coverage from the AOV pass
    c = time.process_time()
    out = render_frame(scene.meshes, scene.emitter, scene.camera, st, list(layers), seed, exposure=scene.exposure)
    c = time.process_time() - c
    return (out.layers, out.seconds.get("beauty", 0.0)) + ((c, out.info) if cpu else ())


def reference(scene, depth: int, args, cache: Path, sampler: str, chunks: int, tag: str, rr: int | None = None):
    """Mean of `chunks` renders of args.ref_chunk_spp spp, the per-pixel variance of that mean, and the mask."""
    import mitsuba

    key = f"{scene.name}_{scene.subject}_{scene.camera.width}_d{depth}r{rr}_{sampler}_{chunks}x{args.ref_chunk_spp}_" \
          f"s{args.seed}_" \
          f"m{mitsuba.__version__}_t{scene.triangles}_v1"
    path = cache / f"sampler_ref_{key}.npz"
    if path.is_file():
        with np.load(path) as z:
            return z["mean"], z["var"], z["mask"], True
    s1 = s2 = None
    for k in range(chunks):
        lay, _ = _render(scene, sampler, args.ref_chunk_spp, depth,
                         seed=20_000_000 + 7919 * k + (0 if tag == "ld" else 1), rr=rr)
        x = lay["image"].astype(np.float64)
        s1 = x if s1 is None else s1 + x
        s2 = x * x if s2 is None else s2 + x * x
    mean = s1 / chunks
    var = np.maximum(s2 / chunks - mean * mean, 0.0) * chunks / (chunks - 1) / chunks  # variance of the mean
    lay, _ = _render(scene, "ldsampler", 4, depth, seed=31, layers=("mask",), aov_spp=256)
    cache.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, mean=mean, var=var, mask=lay["mask"])
    os.replace(tmp, path)
    return mean, var, lay["mask"], False


class Box:
    """relMSE over the evaluator's default region of a reference (its dilated mask box), reference noise removed."""

    def __init__(self, mean: np.ndarray, var: np.ndarray, mask: np.ndarray, exposure: float):
        from bench_tradeoff import Scorer

        self.scorer = Scorer({"image": mean.astype(np.float32), "mask": mask}, exposure)
        r = self.scorer.region
        self.sl = (slice(r.y0, r.y1), slice(r.x0, r.x1))
        self.e = exposure
        self.r = mean[self.sl] * exposure
        self.den = self.r ** 2 + RELMSE_EPS
        self.floor = float(np.mean(var[self.sl] * exposure ** 2 / self.den))

    def relmse(self, x: np.ndarray) -> float:
        d = x[self.sl].astype(np.float64) * self.e - self.r
        return float(np.mean(d * d / self.den)) - self.floor


def fit(spps, errs) -> tuple[float, float]:
    s, c = np.polyfit(np.log10(np.asarray(spps, float)), np.log10(np.maximum(np.asarray(errs, float), 1e-30)), 1)
    return float(s), float(10 ** c)


def table(title: str, header: list[str], rows: list[list]) -> str:
    from bench_tradeoff import table as _table

    return _table(title, header, rows)


def pair_psnr(scene, sampler: str, spp: int, depth: int, seeds: tuple[int, int], mask: np.ndarray,
              env_spp: int | None = None, aov_spp: int = 4, tiers: tuple[int, ...] | None = None,
              rr: int | None = None):
    """PSNR vs a converged reference estimated from two independent renders (+3.01 dB); beauty seconds; the
    frame's CPU seconds; the first render's image and render info."""
    from bench_tradeoff import Scorer

    a, ta, ca, info = _render(scene, sampler, spp, depth, seeds[0], env_spp=env_spp, aov_spp=aov_spp, tiers=tiers,
                              cpu=True, rr=rr)
    b, tb, cb, _ = _render(scene, sampler, spp, depth, seeds[1], env_spp=env_spp, aov_spp=aov_spp, tiers=tiers,
                           cpu=True, rr=rr)
    sc = Scorer({"image": b["image"], "mask": mask}, scene.exposure)
    return sc.psnr(a["image"]) + 10 * math.log10(2.0), (ta + tb) / 2, (ca + cb) / 2, a["image"], info


def sweep(args, scene_name: str, results: dict, report: list) -> None:
    from bench_tradeoff import build_scene, SCENE_CLASS
    from rh_dataset.render.sampler import taken_spp
    from rh_dataset.presets import load_presets

    depth = load_presets()["standard"].depth_for(SCENE_CLASS[scene_name])
    rr = load_presets()["standard"].roulette_for(SCENE_CLASS[scene_name])
    scene = build_scene(scene_name, args.resolution, args.seed, subject=args.subject)
    _render(scene, "independent", 1, depth, 0)  # warm-up: kernels compile once (disk cache), not timed
    t = time.perf_counter()
    mean, var, mask, cached = reference(scene, depth, args, Path(args.cache), "ldsampler", args.ref_chunks, "ld", rr)
    mi_, vi_, _, _ = reference(scene, depth, args, Path(args.cache), "independent", args.check_chunks, "ind", rr)
    box = Box(mean, var, mask, scene.exposure)
    sl = box.sl
    # a ratio of box means: a per-pixel ratio would divide by noisy variance estimates (biased high at few chunks)
    chi = float(np.mean((mean[sl] - mi_[sl]) ** 2) / np.mean(var[sl] + vi_[sl]))
    R = {"depth": depth, "reference": {"sampler": "ldsampler", "chunks": args.ref_chunks, "chunk_spp": args.ref_chunk_spp,
                                       "relmse_floor": box.floor, "check_independent_chunks": args.check_chunks,
                                       "ld_vs_independent_normalised_sq_diff": chi, "cached": cached,
                                       "seconds": time.perf_counter() - t}, "samplers": {}}
    results["sweep"][scene_name] = R
    print(f"\n## {scene_name} at {args.resolution}x{args.resolution}, depth {depth}: reference ldsampler "
          f"{args.ref_chunks} x {args.ref_chunk_spp} spp ({'cached' if cached else 'rendered'}), its relMSE floor "
          f"{box.floor:.2e}; ldsampler vs independent ({args.check_chunks} x {args.ref_chunk_spp}) reference: mean "
          f"normalised squared difference {chi:.3f} (1 = same image)", flush=True)
    # AOV pass: coverage, albedo and normal errors vs aov spp, against the ldsampler AOV pass at --ref-aov-spp
    from bench_tradeoff import Scorer

    aov_layers = ("mask", "albedo", "normal")
    ref_aov, _ = _render(scene, "ldsampler", 4, depth, seed=77, layers=aov_layers, aov_spp=args.ref_aov_spp)
    ref_cov = ref_aov["mask"].astype(np.float64)
    aov_scorer = Scorer({"image": mean.astype(np.float32), **ref_aov}, scene.exposure)
    arows = []
    for smp in args.samplers:
        for n in sorted({taken_spp(smp, t) for t in args.aov_targets}):
            errs, alb, nrm = [], [], []
            for k in range(args.seeds):
                lay, _ = _render(scene, smp, 4, depth, seed=3000 + 31 * n + k, layers=aov_layers, aov_spp=n)
                errs.append(float(np.mean((lay["mask"][sl] - ref_cov[sl]) ** 2)))
                e = aov_scorer.aovs(lay)
                alb.append(e["albedo_psnr"])
                nrm.append(e["normal_deg"])
            R["samplers"].setdefault(smp, {}).setdefault("aov", {})[n] = {
                "mask_mse": float(np.mean(errs)), "albedo_psnr": float(np.mean(alb)), "normal_deg": float(np.mean(nrm))}
            arows.append([smp, n, float(np.mean(errs)), float(np.mean(alb)), float(np.mean(nrm))])
    report.append(table(f"{scene_name}: AOV pass vs ldsampler at {args.ref_aov_spp} aov spp (coverage MSE over the box; "
                        f"albedo PSNR and normal error inside the mask, as bench_tradeoff)",
                        ["sampler", "aov spp (taken)", "mask MSE", "albedo PSNR dB", "normal err deg"], arows))
    if args.aov_only:
        return
    rows, fits = [], {}
    for smp in args.samplers:
        counts = sorted({taken_spp(smp, t) for t in args.targets})
        counts = [n for n in counts if n <= args.max_spp]
        pts = []
        _render(scene, smp, counts[0], depth, 1, rr=rr)  # warm-up: each sampler is its own kernel
        for n in counts:
            errs, secs, pairs = [], [], []
            imgs = []
            for k in range(args.seeds):
                lay, b = _render(scene, smp, n, depth, seed=1000 + 31 * n + k, rr=rr)
                errs.append(box.relmse(lay["image"]))
                secs.append(b)
                imgs.append(lay["image"])
            e = float(np.mean(errs))
            vs_ref = box.scorer.psnr(imgs[0])
            pair = (box.scorer.psnr(imgs[0], reference=imgs[1]) + 10 * math.log10(2.0)) if len(imgs) > 1 else float("nan")
            pts.append({"spp": n, "relmse": e, "relmse_seeds": errs, "seconds": float(np.mean(secs)),
                        "psnr_vs_ref": vs_ref, "psnr_pair_estimate": pair})
            rows.append([smp, n, float(np.mean(secs)), n * args.resolution ** 2 / np.mean(secs) / 1e6, e,
                         box.floor / e, vs_ref, pair])
        s, c = fit([p["spp"] for p in pts], [p["relmse"] for p in pts])
        fits[smp] = (s, c)
        R["samplers"].setdefault(smp, {}).update(points=pts, slope=s, relmse_at_1spp=c)
    report.append(table(f"{scene_name}: beauty relMSE vs spp, {args.resolution}x{args.resolution}, depth {depth}, "
                        f"mean of {args.seeds} seeds, reference noise removed",
                        ["sampler", "spp (taken)", "beauty s", "Msamples/s", "relMSE", "ref floor / relMSE",
                         "PSNR dB vs ref", "PSNR dB pair est."], rows))
    ind_s, ind_c = fits.get("independent", (None, None))
    rows = []
    for smp, (s, c) in fits.items():
        eq = {}
        for n in (16, 128):  # spp this sampler needs for the error independent has at n spp (on its own fit)
            target = ind_c * n ** ind_s if ind_c else float("nan")
            eq[n] = (target / c) ** (1 / s) if ind_c else float("nan")
        R["samplers"][smp]["spp_for_independent_error"] = eq
        rows.append([smp, s, c, eq[16], eq[128]])
    report.append(table(f"{scene_name}: fitted log10 relMSE = log10 C + slope log10 spp",
                        ["sampler", "slope", "C (relMSE at 1 spp)", "spp for independent's error at 16",
                         "... at 128"], rows))


def floors(args, results: dict, report: list) -> None:
    """Each --floor configuration's noise floor (pair estimate) and time on each scene. With --floor-repeats R the
    configurations are rendered in turn, R rounds (every round a pair of fresh seeds per configuration): the PSNR is
    the mean over the rounds, the seconds their medians, so a load that drifts during the run falls on every
    configuration alike."""
    from bench_tradeoff import build_scene, SCENE_CLASS
    from rh_dataset.presets import load_presets

    presets = load_presets()
    rows = []
    for name in args.scenes:
        scene = build_scene(name, args.floor_resolution, args.seed, subject=args.subject)
        mask, _ = _render(scene, "ldsampler", 4, 2, seed=31, layers=("mask",), aov_spp=64)
        configs = []
        for item in args.floor:
            pname, smp, spp, *rest = item.split(":")
            env_spp = int(rest[0]) if rest and rest[0] else None
            tiers = tuple(int(v) for v in rest[1][1:].split("-")) if len(rest) > 1 else None
            depth = presets[pname].depth_for(SCENE_CLASS[name])
            rr = presets[pname].roulette_for(SCENE_CLASS[name])
            aov_spp = presets[pname].aov_spp if presets[pname].sampler == smp else 4
            configs.append((pname, smp, int(spp), env_spp, tiers, depth, aov_spp, rr))
            _render(scene, smp, int(spp), depth, 0, env_spp=env_spp, aov_spp=aov_spp, tiers=tiers, rr=rr)  # warm-up
        runs: list[list] = [[] for _ in configs]
        for r in range(args.floor_repeats):
            for i, (pname, smp, spp, env_spp, tiers, depth, aov_spp, rr) in enumerate(configs):
                seeds = (4242 + 2 * r, 4243 + 2 * r)
                psnr, secs, cpu, _, info = pair_psnr(scene, smp, spp, depth, seeds, mask["mask"], env_spp, aov_spp,
                                                     tiers, rr)
                runs[i].append((psnr, secs, cpu, info.get("focus", {}).get("pixels_per_tier")))
                print(f"  {name} round {r}: {pname} {smp} {spp} spp (env {env_spp}, tiers {tiers} {runs[i][-1][3]}): "
                      f"{psnr:.2f} dB, beauty {secs:.2f} s, frame CPU {cpu:.2f} s", flush=True)
        for (pname, smp, spp, env_spp, tiers, depth, aov_spp, roulette), rr in zip(configs, runs):
            psnr = float(np.mean([x[0] for x in rr]))
            secs, cpu = float(np.median([x[1] for x in rr])), float(np.median([x[2] for x in rr]))
            results["floors"].append({"scene": name, "preset": pname, "sampler": smp, "spp": spp, "env_spp": env_spp,
                                      "adaptive_tiers": tiers, "pixels_per_tier": rr[0][3], "depth": depth,
                                      "rr_depth": roulette,
                                      "psnr": psnr, "psnr_rounds": [x[0] for x in rr], "beauty_seconds": secs,
                                      "frame_cpu_seconds": cpu, "resolution": args.floor_resolution})
            rows.append([name, pname, smp, spp, env_spp or "-", "-".join(map(str, tiers)) if tiers else "-",
                         f"{depth}" + (f" (roulette from {roulette})" if roulette else ""), secs, cpu, psnr])
    report.append(table(f"noise floor at {args.floor_resolution}x{args.floor_resolution}: PSNR vs a converged "
                        f"reference, estimated from two independent renders (+3.01 dB), mean of "
                        f"{args.floor_repeats} round(s); seconds: medians",
                        ["scene", "preset", "sampler", "spp", "env spp", "adaptive tiers", "depth", "beauty s",
                         "frame CPU s", "PSNR dB (person)"], rows))


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=["interior-apose", "sunrise-random"],
                   help="bench_tradeoff.py's reference scenes: interior-apose, sunrise-random (default both)")
    p.add_argument("--samplers", nargs="+", default=list(SAMPLER_NAMES), choices=SAMPLER_NAMES,
                   help="Mitsuba samplers of the sweep (default all five)")
    p.add_argument("--resolution", type=int, default=128, help="sweep resolution (default 128)")
    p.add_argument("--targets", type=int, nargs="+", default=[4, 16, 64, 256],
                   help="requested spp; each sampler renders the counts it takes nearest to these")
    p.add_argument("--max-spp", type=int, default=256, help="largest count of the sweep (render_frame's one-call limit)")
    p.add_argument("--seeds", type=int, default=2,
                   help="renders per sample count in the sweeps, each with its own seed; their errors are "
                        "averaged (default 2)")
    p.add_argument("--ref-chunks", type=int, default=256, help="ldsampler reference: number of chunks")
    p.add_argument("--ref-chunk-spp", type=int, default=256,
                   help="spp of each reference chunk, ldsampler and independent alike (default 256)")
    p.add_argument("--ref-aov-spp", type=int, default=1024, help="ldsampler AOV reference")
    p.add_argument("--aov-targets", type=int, nargs="+", default=[4, 16, 64], help="requested aov spp of the AOV table")
    p.add_argument("--aov-only", action="store_true", help="the sweep measures the AOV pass only (no beauty sweep)")
    p.add_argument("--check-chunks", type=int, default=64, help="independent reference for the bias check: chunks")
    p.add_argument("--floor", nargs="*", default=["draft:independent:16", "draft:multijitter:16",
                                                  "standard:independent:128", "standard:multijitter:48",
                                                  "standard:multijitter:64"],
                   help="preset:sampler:spp[:env_spp[:aTIERS]] whose noise floor is measured at --floor-resolution "
                        "(env_spp: the focused beauty pass, rh_dataset.render.focus; aTIERS, e.g. "
                        "a16-36-64-100-169-256: samples by noise, rh_dataset.render.adaptive, spp their mean over "
                        "the person)")
    p.add_argument("--floor-resolution", type=int, default=512,
                   help="frame width and height in pixels of the --floor renders (default 512)")
    p.add_argument("--floor-repeats", type=int, default=1, help="rounds of every --floor configuration, interleaved")
    p.add_argument("--skip-sweep", action="store_true", help="leave out the sweep (and the references it needs)")
    p.add_argument("--skip-floor", action="store_true", help="leave out the --floor noise floors")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the scenes (their character and random pose, bench_tradeoff.build_scene); part of "
                        "the references' cache key (default 0)")
    p.add_argument("--subject", type=int, default=0,
                   help="benchmark subject in the scenes (bench_tradeoff.build_scene)")
    p.add_argument("--cache", default="/tmp/rh_ref",
                   help="folder of the cached references, sampler_ref_*.npz (default /tmp/rh_ref)")
    p.add_argument("--out", default=None, help="write the results JSON here")
    args = p.parse_args(argv)

    from rh_dataset.variant import select_variant

    variant = select_variant(None)
    print(f"bench_sampler: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at the start; {variant}",
          flush=True)
    results: dict = {"args": vars(args), "variant": variant, "sweep": {}, "floors": [],
                     "load_start": os.getloadavg()[0]}
    report: list[str] = []
    t0 = time.perf_counter()
    if not args.skip_sweep:
        for name in args.scenes:
            sweep(args, name, results, report)
    if not args.skip_floor and args.floor:
        floors(args, results, report)
    results["load_end"] = os.getloadavg()[0]
    print(f"\nload average {results['load_start']:.2f} at the start, {results['load_end']:.2f} at the end; "
          f"{time.perf_counter() - t0:.0f} s", flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=1, default=float))
    return results


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    main()
