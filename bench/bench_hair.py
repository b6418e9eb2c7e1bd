"""Where the beauty pass's time goes with strand hair: the strands' BSDF as the generator builds it against plain
`hair` and against no strands, the cost of a sample by what the camera ray hits first, and (--curves) the strands
drawn as polylines instead of splines.

    python bench/bench_hair.py                                  # 512x512, both scenes, subject 0, 3 repeats
    python bench/bench_hair.py --scenes sunrise-random --subjects 0 8 --repeats 5
    python bench/bench_hair.py --figure docs/hair_depth.png --subjects 44 --scenes interior-apose   # old cut vs now
    python bench/bench_hair.py --curves 4 8 --subjects 0 8            # spline vs polyline strands: time and error
    python bench/bench_hair.py --depths --subjects 0 8                # what a hair sample costs, bounce by bounce

Variants (bench_tradeoff's scenes; `--subjects`: benchmark subjects in the scene's pose, light and camera fill):
  wrapper   the strands' BSDF as today: strand_shape.HAIR_WITH_ALBEDO, a Python BSDF whose scattering queries go to
            Mitsuba's `hair` and whose diffuse reflectance (the AOV pass's albedo) is the fibre's albedo;
  plain     Mitsuba's `hair` itself on the curves (registered here under another name; the AOV pass's albedo of the
            hair is then ~0, which is why the generator does not use it);
  none      no strands (the meshes only).
Each renders one frame as the `standard` preset does (AOV pass, then the focused beauty pass at the scene class's
depth), same seed for every variant, interleaved, --repeats times after an untimed warm-up of each. Reported: the
medians of scene-load and beauty wall seconds and of the frame's process CPU seconds (they move less with the shared
machine's load than wall seconds), whether the wrapper's and plain images are bit-identical, and the operation counts
of the frame's two largest kernels (drjit's kernel history: the beauty pass's path tracer and the AOV pass): equal
counts mean the wrapper adds nothing to what the kernels compute.

Cost by first hit: an `aov` pass of `shape_index` at 1 spp labels each of the person's pixels by the shape its camera
ray hits first (none: the environment); each label's pixels are traced at --cost-spp through `render_pixels` (the
focused pass's own tracer, hair BSDF as today), and the CPU microseconds per sample are printed with each label's
share of the pixels, of the pass's CPU time, and of the noise of a standard frame (the squared display-space
difference of two renders with their own seeds, as bench_sampler.py's floor pairs: where the error the floor
measures lies). Groups of fewer than 100 pixels are left out.

--depths [D ...]: instead, what in a sample costs (docs/TRADEOFFS.md, "What a hair sample costs"): the cost by
first hit at each max depth D (default 1 2 3 4 6 8 16 64, Russian roulette from the class's depth as the preset
renders), with the strands' BSDF as built and with a diffuse stand-in of the fibre's albedo on the same curves. Depth
1 is the camera ray alone; each depth more adds a bounce (an emitter sample and its shadow ray, a BSDF sample and its
ray). Each figure is the CPU time of tracing the group's pixels twice over less that of once (the call's fixed cost
taken out); last, by arithmetic, the CPU seconds of a whole focused pass at the preset's count at those rates.

--curves [M ...]: instead, the strands' primitive (docs/TRADEOFFS.md, "Strands as polylines"): Mitsuba's
`bsplinecurve` of the control points (what every preset draws) against the `linearcurve` through the spline at M
points a segment (`polylines` here; default M: 8). First straight fibres, where a polyline is its spline exactly:
one, and a stack of 12, under a uniform white environment, without and with melanin, the mean of the pixels both
primitives cover (Mitsuba's `hair` BSDF is specified for `bsplinecurve`). Then the geometry: each polyline piece's
largest distance from the stretch of spline it stands for (the spline sampled 64 times a segment), over every strand
of the frame, by fibre. Then a standard frame of each, interleaved, --repeats times (at least 2): medians of beauty
wall and frame CPU seconds; and the image, from those renders (each repeat its own seed), in display space over the
person's region as rh-eval scores it (PSNR = -10 log10 MSE). "noise": a primitive's renders against each other, every
pair of seeds, plus 3.01 dB (each render against its converged image); "bias": how far the converged images of the
two primitives lie apart, estimated as the mean squared error of the polyline's renders against the spline's of other
seeds less the mean of both primitives' own noise.

--curves ... --figure PATH: also a picture of that run, one column per subject and scene, top to bottom: the head in
the spline's renders (averaged over the repeats), in the last M's polyline's, their difference x4 about grey, and
the noise such a difference would show with no bias (two of the spline's renders' difference x4 / sqrt(repeats)).

--figure PATH (alone): instead, the head of each --subjects in each --scenes (top: the standard preset with the plain
cut it had before, depth 3 / 4 by class; bottom: as now, the class's Russian roulette up to its max depth), same seed,
in display space (the frame's exposure, sRGB), 3x enlarged: what the truncated bounces took from the hair.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import bench_tradeoff as bt  # noqa: E402  (the fixed scenes)

PLAIN_HAIR = "rh_bench_plain_hair"


def _register_plain(mi) -> None:
    # A factory that hands back the nested `hair` BSDF itself (reading `albedo` so that Mitsuba's parser does not
    # refuse it as unused): the curves then carry exactly Mitsuba's hair BSDF, no Python in between.
    mi.register_bsdf(PLAIN_HAIR, lambda props: (props["albedo"], props["hair"])[1])


def render(scene, variant: str, settings, seed: int):
    """One frame of `variant`: (FrameRender, process CPU seconds, JIT kernel operation counts)."""
    import drjit as dr

    import rh_dataset.characters.strand_shape as strand_shape
    from rh_dataset.render.passes import render_frame

    meshes = [m for m in scene.meshes if not hasattr(m, "fibre")] if variant == "none" else scene.meshes
    name = strand_shape.HAIR_WITH_ALBEDO
    strand_shape.HAIR_WITH_ALBEDO = PLAIN_HAIR if variant == "plain" else name
    dr.kernel_history()
    c = time.process_time()
    try:
        out = render_frame(meshes, scene.emitter, scene.camera, settings, ["image", "mask"], seed,
                           exposure=scene.exposure)
    finally:
        strand_shape.HAIR_WITH_ALBEDO = name
    cpu = time.process_time() - c
    ops = [int(k.get("operation_count", 0)) for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT]
    return out, cpu, ops


def ab(scene, settings, repeats: int) -> list[list]:
    variants = ("wrapper", "plain", "none")
    for v in variants:
        render(scene, v, settings, 1)  # warm-up: compiles (or loads) each variant's kernels
    runs: dict[str, list] = {v: [] for v in variants}
    for r in range(repeats):
        for v in variants:
            runs[v].append(render(scene, v, settings, 4242))
    same = all(np.array_equal(a[0].layers["image"], b[0].layers["image"])
               for a, b in zip(runs["wrapper"], runs["plain"]))
    rows = []
    for v in variants:
        load = float(np.median([o.seconds["load"] for o, _, _ in runs[v]]))
        beauty = float(np.median([o.seconds["beauty"] for o, _, _ in runs[v]]))
        cpu = float(np.median([c for _, c, _ in runs[v]]))
        ops = runs[v][-1][2]
        rows.append([v, load, beauty, cpu, " / ".join(map(str, sorted(ops)[-2:][::-1])),
                     ("bit-identical to wrapper" if same else "DIFFERS from wrapper") if v == "plain" else "-"])
    base = rows[0]
    for row in rows:
        row.insert(4, row[3] / base[3])
    return rows


def first_hit_groups(s, settings, min_pixels: int = 100) -> tuple[list[tuple[str, np.ndarray]], np.ndarray]:
    """The person's pixels of the loaded scene `s` (the `standard` frame's focus: the AOV pass's coverage, dilated
    by FOCUS_MARGIN) grouped by the shape their camera ray hits first, from an `aov` pass of `shape_index` at 1 spp
    (0 for a miss, shown as "(environment)"; else 1 + the shape's position in scene.shapes(): checked on the scenes
    here, the hair's pixels sit on the head). Returns [(shape id, flat pixel indices)], groups of fewer than
    `min_pixels` left out, and all the person's pixels (for shares)."""
    import mitsuba as mi

    from rh_dataset.render.focus import person_pixels
    from rh_dataset.render.passes import FOCUS_MARGIN, _AOV_INTEGRATOR

    cov = np.array(mi.render(s, integrator=mi.load_dict(_AOV_INTEGRATOR), spp=settings.aov_spp, seed=1))[..., 3]
    pix = person_pixels(np.clip(cov, 0.0, 1.0), FOCUS_MARGIN)
    first = np.array(mi.render(s, integrator=mi.load_dict({"type": "aov", "aovs": "si:shape_index"}), spp=1,
                               seed=1))[..., -1].reshape(-1)[pix].astype(int)
    names = ["(environment)"] + [sh.id() for sh in s.shapes()]
    groups = [(names[k] if k < len(names) else f"shape {k}", pix[first == k]) for k in np.unique(first)]
    return [(n, sel) for n, sel in groups if len(sel) >= min_pixels], pix


def cost_by_first_hit(scene, settings, spp: int) -> list[list]:
    """CPU microseconds per sample of the person's pixels grouped by the shape their camera ray hits first, and each
    group's share of the frame's noise: the squared display-space difference (sRGB of the exposed radiance, as
    rh-eval scores) of two `settings` renders with their own seeds (bench_sampler.py's pair), summed over its
    pixels."""
    import mitsuba as mi

    from rh_common.colourspace import to_display
    from rh_dataset.render.focus import render_pixels
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import scene_dict

    # The pair first: a live scene below would make render_frame's own load compile its kernels again.
    pair = [to_display(render_frame(scene.meshes, scene.emitter, scene.camera, settings, ["image", "mask"], seed,
                                    exposure=scene.exposure).layers["image"], scene.exposure)
            for seed in (4242, 4243)]
    noise = np.sum((pair[0].astype(np.float64) - pair[1]) ** 2, axis=-1).reshape(-1)

    s = mi.load_dict(scene_dict(scene.meshes, scene.emitter, scene.camera,
                                {"type": "path", "max_depth": int(settings.max_depth), "hide_emitters": False,
                                 **({"rr_depth": settings.rr_depth} if settings.rr_depth else {})},
                                settings.spp, pixel_format="rgba", sampler=settings.sampler))
    try:
        groups, pix = first_hit_groups(s, settings)
        rows, total, all_noise = [], 0.0, noise[pix].sum()
        for name, sel in groups:
            render_pixels(mi, s, sel, spp, 1)  # warm-up (and the kernel, once)
            c = time.process_time()
            render_pixels(mi, s, sel, spp, 2)
            c = time.process_time() - c
            total += c
            rows.append([name, len(sel), len(sel) / len(pix), 1e6 * c / (len(sel) * spp), c,
                         noise[sel].sum() / all_noise])
        return [row[:4] + [row[4] / total, row[5]] for row in rows]  # CPU seconds -> share of the pass's
    finally:
        s = None


def cost_by_depth(scene, settings, spp: int, depths: list[int]) -> tuple[list[str], list[list]]:
    """What a sample of each first-hit group costs as its paths are allowed to go deeper: CPU microseconds per
    sample through `render_pixels` at each max depth in `depths` (Russian roulette from the class's depth, as the
    preset renders), with the strands' BSDF as the generator builds it (Mitsuba's `hair`) and with the diffuse
    stand-in of the fibre's albedo on the same curves (`strand_shape.mitsuba_curves(stand_in=True)`). Depth 1 is the
    camera ray alone (its first intersection and the environment it may see); each step deeper adds a bounce: an
    emitter sample with its shadow ray, a BSDF sample and the ray it traces. The hair/stand-in difference at a depth
    is what the `hair` BSDF's own evaluation and sampling cost, and the paths it keeps going, beyond a diffuse
    surface's on the same geometry. Each figure is the difference between tracing the group's pixels twice over
    and once, so the call's fixed cost is not in it. Last, two rows of arithmetic: the CPU seconds a whole focused
    pass at the preset's count would take at those rates. Returns the column names and one row per (group, BSDF)."""
    import functools

    import mitsuba as mi

    from rh_dataset.characters import strand_shape
    from rh_dataset.render.focus import render_pixels
    from rh_dataset.render.scene import scene_dict

    def load(depth: int, stand_in: bool):
        orig = strand_shape.mitsuba_curves
        if stand_in:
            strand_shape.mitsuba_curves = functools.partial(orig, stand_in=True)
        try:
            integ = {"type": "path", "max_depth": int(depth), "hide_emitters": False,
                     **({"rr_depth": settings.rr_depth} if settings.rr_depth else {})}
            return mi.load_dict(scene_dict(scene.meshes, scene.emitter, scene.camera, integ, settings.spp,
                                           pixel_format="rgba", sampler=settings.sampler))
        finally:
            strand_shape.mitsuba_curves = orig

    s = load(settings.max_depth, False)
    groups = first_hit_groups(s, settings)[0]
    s = None
    us: dict[tuple[str, bool, int], float] = {}
    for stand_in in (False, True):
        for depth in depths:
            s = load(depth, stand_in)
            try:
                for name, sel in groups:
                    render_pixels(mi, s, sel, spp, 1)  # warm-up (and the kernel, once)
                    # A call's fixed cost (tracing the kernel, the Python BSDF included, and looking it up) is
                    # taken out: the group's pixels once and twice, the difference is the cost of its samples.
                    t = []
                    for pixels in (sel, np.concatenate([sel, sel])):
                        c = time.process_time()
                        render_pixels(mi, s, pixels, spp, 2)
                        t.append(time.process_time() - c)
                    us[name, stand_in, depth] = 1e6 * (t[1] - t[0]) / (len(sel) * spp)
            finally:
                s = None
    rows = []
    for name, sel in groups:
        # every group twice: the stand-in changes only what the strands scatter, so the other groups' rows show
        # what their paths' bounces into the hair cost
        for stand_in in (False, True):
            rows.append([name, len(sel), "diffuse stand-in" if stand_in else "hair"]
                        + [us[name, stand_in, d] for d in depths])
    # What a whole focused pass of the preset's count would cost at these rates: the sum over the groups (every
    # person pixel is in one) of pixels x us x spp, in CPU seconds (the beauty pass keeps 2 cores busy: wall ~ half).
    for stand_in in (False, True):
        rows.append([f"all: CPU s of a {settings.spp}-spp pass", sum(len(sel) for _, sel in groups),
                     "diffuse stand-in" if stand_in else "hair"]
                    + [1e-6 * settings.spp * sum(len(sel) * us[name, stand_in, d] for name, sel in groups)
                       for d in depths])
    return [f"depth {d}" for d in depths], rows


def _basis(t: np.ndarray) -> np.ndarray:
    """The uniform cubic B-spline's basis at t in [0, 1): (len(t), 4); on segment j, sum_i B_i(t) P_(j+i)."""
    return np.stack([(1 - t) ** 3, 3 * t ** 3 - 6 * t ** 2 + 4, -3 * t ** 3 + 3 * t ** 2 + 3 * t + 1, t ** 3], 1) / 6.0


def polylines(points: np.ndarray, radius: np.ndarray, per_segment: int) -> tuple[np.ndarray, np.ndarray]:
    """The polyline through each strand's spline as the generator draws it (the control points, the first and last
    repeated twice more: K + 1 segments of a uniform cubic B-spline from the root to the tip), `per_segment` points
    a segment, then the tip: (S, K, 3), (S, K) -> (S, N, 3), (S, N) float64, N = (K + 1) * per_segment + 1; the
    radius the same spline of the control points' radii."""
    P = np.asarray(points, dtype=np.float64)
    R = np.asarray(radius, dtype=np.float64)
    P = np.concatenate([P[:, :1], P[:, :1], P, P[:, -1:], P[:, -1:]], 1)
    R = np.concatenate([R[:, :1], R[:, :1], R, R[:, -1:], R[:, -1:]], 1)
    b = _basis(np.arange(per_segment, dtype=np.float64) / per_segment)
    win = np.arange(P.shape[1] - 3)[:, None] + np.arange(4)[None, :]  # each segment's 4 control points
    pts = np.einsum("mk,snkd->snmd", b, P[:, win]).reshape(len(P), -1, 3)
    rad = np.einsum("mk,snk->snm", b, R[:, win]).reshape(len(R), -1)
    return np.concatenate([pts, P[:, -1:]], 1), np.concatenate([rad, R[:, -1:]], 1)


def linear_curves(strands, stand_in: bool = False, *, per_segment: int, generator_curves):
    """The strands as a `linearcurve` through their splines (`polylines`), with the BSDF of the shape
    `generator_curves` (the generator's `strand_shape.mitsuba_curves`) builds: the --curves variant."""
    import tempfile

    import mitsuba as mi

    from rh_dataset.variant import jit_array

    bsdf = generator_curves(strands, stand_in).bsdf()
    Q, R = polylines(strands.points, strands.radius, per_segment)
    S, n = R.shape
    cp = np.concatenate([Q, R[..., None]], -1).astype(np.float32).reshape(-1)
    seg = (np.arange(S, dtype=np.uint32)[:, None] * n + np.arange(n - 1, dtype=np.uint32)[None, :]).ravel()
    with tempfile.TemporaryDirectory(prefix="rh_bench_curves_") as tmp:
        (Path(tmp) / "s.txt").write_text("0 0 0 0.001\n0 0 1 0.001\n")
        shape = mi.load_dict({"type": "linearcurve", "filename": str(Path(tmp) / "s.txt"), "bsdf": bsdf})
    params = mi.traverse(shape)
    params["control_points"] = jit_array(mi.Float, cp)
    params["segment_indices"] = jit_array(mi.UInt32, seg)
    params["control_point_count"] = int(S * n)
    params.update()
    return shape


def _drawn_with(per_segment: int):
    """A context in which render_frame draws strands as polylines of `per_segment` points a segment (0: as the
    generator does, splines): the scene dict takes `strand_shape.mitsuba_curves` at call time."""
    import contextlib
    import functools

    from rh_dataset.characters import strand_shape

    @contextlib.contextmanager
    def ctx():
        orig = strand_shape.mitsuba_curves
        if per_segment:
            strand_shape.mitsuba_curves = functools.partial(linear_curves, per_segment=per_segment,
                                                            generator_curves=orig)
        try:
            yield
        finally:
            strand_shape.mitsuba_curves = orig
    return ctx()


def chord_deviation(strands, per_segment: int, dense: int = 64) -> np.ndarray:
    """Each polyline piece's distance from the spline it stands for, at `dense` samples a spline segment (metres)."""
    fine, _ = polylines(strands.points, strands.radius, dense)
    poly, _ = polylines(strands.points, strands.radius, per_segment)
    i = np.arange(fine.shape[1] - 1)
    piece = (i // dense) * per_segment + (i % dense) * per_segment // dense  # the piece each sample falls on
    a, b, q = poly[:, piece], poly[:, piece + 1], fine[:, :-1]
    d = b - a
    u = np.clip(((q - a) * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-30), 0.0, 1.0)
    return np.linalg.norm(q - (a + u[..., None] * d), axis=-1).ravel()


def straight_fibres(spp: int = 512) -> list[list]:
    """Straight fibres, where a polyline is its spline exactly, under a uniform white environment, seen side-on:
    the mean of the pixels both primitives cover fully, for one fibre and for a stack of 12 touching ones, with
    zero melanin (the white furnace: 1 for an energy-conserving fibre) and with some (a light brown)."""
    from rh_common.camera import Camera
    from rh_dataset.characters.character import PosedStrands
    from rh_dataset.characters.hair_fibre import HairFibre
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings

    cam = Camera(64, 64, 10.0, (0.0, -6.0, 0.1), (0.0, 0.0, 0.1))
    white = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    x = np.linspace(-0.5, 0.5, 6)
    rows = []
    for n in (1, 12):
        pts = np.stack([np.stack([x, 0 * x, 0 * x + 0.04 * k], 1) for k in range(n)]).astype(np.float32)
        for fibre in (HairFibre(0.0, 0.0), HairFibre(0.3, 0.1)):
            s = PosedStrands("s", pts, np.full(pts.shape[:2], 0.02, np.float32), fibre)
            outs = {}
            for per in (0, 8):
                with _drawn_with(per):
                    outs[per] = render_frame([s], white, cam, RenderSettings(spp=spp, aov_spp=16, max_depth=64),
                                             ["image", "mask"], 3)
            both = (outs[0].layers["mask"] > 0.999) & (outs[8].layers["mask"] > 0.999)
            means = [outs[per].layers["image"][both].mean(0) for per in (0, 8)]
            rows.append([f"{n} fibre{'s' if n > 1 else ''}", f"{fibre.eumelanin} / {fibre.pheomelanin}",
                         " / ".join(f"{v:.4f}" for v in means[0]), " / ".join(f"{v:.4f}" for v in means[1]),
                         float(means[1].mean() / means[0].mean()), int(both.sum())])
    return rows


def curves(scene, settings, per_segments, repeats: int) -> tuple[list[list], list[list], np.ndarray]:
    """The --curves tables for one scene: geometry rows, then time and image rows (see the module docstring), and
    its picture's column."""
    import math

    from rh_dataset.render.passes import render_frame

    geo = []
    for m in scene.meshes:
        if hasattr(m, "fibre"):
            for per in per_segments:
                dev = chord_deviation(m, per)
                geo.append([m.name, f"{len(m.points)} x {m.points.shape[1]}", per,
                            len(m.points) * ((m.points.shape[1] + 1) * per + 1), 1e6 * dev.max(),
                            1e6 * np.percentile(dev, 99), 1e6 * np.median(dev), 1e3 * float(np.median(m.radius))])
    variants = {"bsplinecurve": 0, **{f"linearcurve, {per} a segment": per for per in per_segments}}

    def one(name, seed):
        with _drawn_with(variants[name]):
            c = time.process_time()
            out = render_frame(scene.meshes, scene.emitter, scene.camera, settings, ["image", "mask"], seed,
                               exposure=scene.exposure)
            return out, time.process_time() - c

    for name in variants:
        one(name, 1)  # warm-up: each primitive's kernels
    runs = {name: [] for name in variants}
    for r in range(max(repeats, 2)):
        for name in variants:
            runs[name].append(one(name, 4242 + r))
    ref = runs["bsplinecurve"]
    mask = ref[0][0].layers["mask"]

    def mse(a, b):
        sc = bt.Scorer({"image": b, "mask": mask}, scene.exposure)
        return 10.0 ** (-sc.psnr(a) / 10.0)

    def pairs(xs, ys):  # mean squared error over every pair of renders of different seeds
        return float(np.mean([mse(x[0].layers["image"], y[0].layers["image"])
                              for i, x in enumerate(xs) for j, y in enumerate(ys) if i != j]))

    same = pairs(ref, ref)
    rows = []
    for name, rs in runs.items():
        beauty = float(np.median([o.seconds["beauty"] for o, _ in rs[:repeats]]))
        cpu = float(np.median([c for _, c in rs[:repeats]]))
        own = pairs(rs, rs)
        err = f"noise {-10 * math.log10(own / 2):.2f} dB"
        if name != "bsplinecurve":
            bias = pairs(rs, ref) - 0.5 * (same + own)  # the cross pairs' error less both images' own noise
            err += f", bias {-10 * math.log10(bias):.2f} dB" if bias > 0 else ", bias within noise"
        rows.append([name, beauty, cpu, err])
    base = rows[0]
    for row in rows:
        row.insert(3, row[2] / base[2])
    return geo, rows, _curves_crops(scene, ref, runs[list(variants)[-1]])


def _head_box(mask: np.ndarray) -> tuple[int, int, int]:
    """The head: the top of the person's mask, a square as wide as a sixth of the frame (y0, x0, side)."""
    resolution = mask.shape[1]
    ys, xs = np.nonzero(mask > 0.5)
    top, side = int(ys.min()), resolution // 6
    cx = int(np.median(xs[ys < top + side // 2]))
    return max(top - side // 8, 0), min(max(cx - side // 2, 0), resolution - side), side


def _curves_crops(scene, spline_runs, poly_runs) -> np.ndarray:
    """The --curves picture's column for one scene: the head, the spline's renders averaged, the polyline's
    averaged, their difference x4 about grey, and the spline's first two seeds' difference x4 / sqrt(n) (the noise
    that difference of averages of n renders would show with no bias)."""
    from rh_common.colourspace import to_display

    disp = [[to_display(o.layers["image"], scene.exposure) for o, _ in rs] for rs in (spline_runs, poly_runs)]
    y0, x0, side = _head_box(spline_runs[0][0].layers["mask"])
    b, p = (np.mean(d, axis=0)[y0:y0 + side, x0:x0 + side] for d in disp)
    noise = (disp[0][0] - disp[0][1])[y0:y0 + side, x0:x0 + side] / np.sqrt(len(disp[0]))
    return np.concatenate([b, p, 0.5 + 4 * (p - b), 0.5 + 4 * noise], axis=0)


def _save_picture(path: Path, columns) -> None:
    from PIL import Image

    img = np.concatenate(columns, axis=1)
    img = np.repeat(np.repeat(img, 3, axis=0), 3, axis=1)
    Image.fromarray((np.clip(img, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)).save(path)
    print(f"wrote {path}", flush=True)


def figure(path: Path, scenes, subjects, resolution: int) -> None:
    """Head crops, old plain cut above the class's roulette, one column per subject and scene (see the docstring)."""
    from rh_common.colourspace import to_display
    from rh_dataset.cli import render_settings
    from rh_dataset.presets import load_presets
    from rh_dataset.render.passes import render_frame

    standard = load_presets()["standard"]
    columns = []
    for subject in subjects:
        for name in scenes:
            scene = bt.build_scene(name, resolution, subject=subject)
            cls = bt.SCENE_CLASS[name]
            now = dataclasses.replace(render_settings("standard", max_depth=standard.depth_for(cls)),
                                      rr_depth=standard.roulette_for(cls))
            before = dataclasses.replace(now, max_depth=standard.roulette_for(cls), rr_depth=None)
            rows = []
            for st in (before, now):
                out = render_frame(scene.meshes, scene.emitter, scene.camera, st, ["image", "mask"], 7,
                                   exposure=scene.exposure)
                rows.append(to_display(out.layers["image"], scene.exposure))
            y0, x0, side = _head_box(out.layers["mask"])
            crops = [r[y0:y0 + side, x0:x0 + side] for r in rows]
            columns.append(np.concatenate(crops, axis=0))
            print(f"  {name}, subject {subject}: depth {before.max_depth} (plain) above depth {now.max_depth} "
                  f"(roulette from {now.rr_depth}); mean display value of the crop {crops[0].mean():.4f} -> "
                  f"{crops[1].mean():.4f}", flush=True)
    _save_picture(path, columns)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", default=list(bt.SCENES), choices=bt.SCENES,
                   help="bench_tradeoff.py's reference scenes rendered (default: both)")
    p.add_argument("--subjects", type=int, nargs="+", default=[0],
                   help="benchmark subjects, each in the scene's pose, light and camera fill (default 0, the "
                        "scenes' own)")
    p.add_argument("--resolution", type=int, default=512, help="frame width and height in pixels (default 512)")
    p.add_argument("--repeats", type=int, default=3,
                   help="timed frames per variant, interleaved, after an untimed warm-up of each; medians are "
                        "printed (default 3)")
    p.add_argument("--cost-spp", type=int, default=64, help="samples per pixel of the cost-by-first-hit table")
    p.add_argument("--depths", type=int, nargs="*", default=None, metavar="D",
                   help="instead of the tables above, the cost by first hit at each max depth D (default 1 2 3 4 6 8 "
                        "16 64; roulette from the class's depth), with the hair BSDF and with a diffuse stand-in on "
                        "the same curves: what in a hair sample costs")
    p.add_argument("--skip-ab", action="store_true",
                   help="leave out the wrapper / plain / none comparison: the cost-by-first-hit table only")
    p.add_argument("--figure", type=Path, default=None,
                   help="write the head crops (old cut / now) here instead; with --curves, that run's head crops "
                        "(spline, the last M's polyline, their difference x4, the noise x4) after its tables")
    p.add_argument("--curves", type=int, nargs="*", default=None, metavar="M",
                   help="instead, the strands' primitive: bsplinecurve against the polyline at each M points a "
                        "spline segment (default 8); straight fibres, geometry, time and image tables")
    args = p.parse_args(argv)

    import drjit as dr
    import mitsuba as mi

    from rh_dataset.cli import render_settings
    from rh_dataset.presets import load_presets
    from rh_dataset.variant import select_variant

    variant = select_variant(None)
    _register_plain(mi)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), "?") if Path("/proc/cpuinfo").exists() else "?"
    print(f"bench_hair: {cpu}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at the start; {variant}; "
          f"{args.resolution}x{args.resolution}", flush=True)
    if args.figure is not None and args.curves is None:
        return figure(args.figure, args.scenes, args.subjects, args.resolution)
    standard = load_presets()["standard"]
    columns = []
    if args.curves is not None:
        bt.table("straight fibres (a polyline is its spline), uniform white light, side-on, 512 spp, depth 64: mean "
                 "of the pixels both primitives cover", ["fibres", "eumelanin / pheomelanin", "bsplinecurve R/G/B",
                                                         "linearcurve R/G/B", "linear / spline", "pixels"],
                 straight_fibres())
    for subject in args.subjects:
        for name in args.scenes:
            scene = bt.build_scene(name, args.resolution, subject=subject)
            cls = bt.SCENE_CLASS[name]
            settings = dataclasses.replace(render_settings("standard", max_depth=standard.depth_for(cls)),
                                           rr_depth=standard.roulette_for(cls))
            strands = sum(len(m.points) for m in scene.meshes if hasattr(m, "fibre"))
            title = (f"{name}, subject {subject} ({strands} strands), standard ({settings.spp} / env "
                     f"{settings.env_spp} spp, depth {settings.max_depth}, roulette from "
                     f"{settings.rr_depth or 'Mitsuba default 5'})")
            if args.curves is not None:
                geo, rows, column = curves(scene, settings, args.curves or [8], args.repeats)
                columns.append(column)
                bt.table(f"{title}: the polyline's distance from the spline",
                         ["fibre", "strands x control points", "points a segment", "polyline points", "max um",
                          "p99 um", "median um", "strand radius median mm"], geo)
                bt.table(f"{title}: the strands' primitive, medians of {args.repeats} interleaved frames",
                         ["primitive", "beauty s", "frame CPU s", "CPU / bsplinecurve",
                          "person PSNR: noise, bias against the spline"], rows)
                continue
            if args.depths is not None:
                depths = sorted(set(args.depths or [1, 2, 3, 4, 6, 8, 16, 64]))
                cols, rows = cost_by_depth(scene, settings, args.cost_spp, depths)
                bt.table(f"{title}: CPU us per sample by first hit and max depth, {args.cost_spp} spp through "
                         "render_pixels", ["first hit", "pixels", "strands' BSDF"] + cols, rows)
                continue
            if not args.skip_ab:
                bt.table(f"{title}: the strands' BSDF, medians of {args.repeats} interleaved frames",
                         ["strands", "scene load s", "beauty s", "frame CPU s", "CPU / wrapper",
                          "ops of the 2 largest kernels", "image"], ab(scene, settings, args.repeats))
            bt.table(f"{title}: cost by first hit, {args.cost_spp} spp through render_pixels",
                     ["first hit", "pixels", "share of pixels", "CPU us / sample", "share of CPU",
                      f"share of the noise ({settings.spp} spp, squared display difference of two seeds)"],
                     cost_by_first_hit(scene, settings, args.cost_spp))
    if columns and args.figure is not None:
        _save_picture(args.figure, columns)
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end", flush=True)


if __name__ == "__main__":
    main()
