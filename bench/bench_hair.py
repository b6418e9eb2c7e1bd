"""Where the beauty pass's time goes with strand hair: the strands' BSDF as the generator builds it against plain
`hair` and against no strands, and the cost of a sample by what the camera ray hits first.

    python bench/bench_hair.py                                  # 512x512, both scenes, subject 0, 3 repeats
    python bench/bench_hair.py --scenes sunrise-random --subjects 0 8 --repeats 5
    python bench/bench_hair.py --figure docs/hair_depth.png --subjects 44 --scenes interior-apose   # old cut vs now

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
share of the pixels and of the pass's CPU time.

--figure PATH: instead, the head of each --subjects in each --scenes (top: the standard preset with the plain cut it
had before, depth 3 / 4 by class; bottom: as now, the class's Russian roulette up to its max depth), same seed, in
display space (the frame's exposure, sRGB), 3x enlarged: what the truncated bounces took from the hair.
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


def cost_by_first_hit(scene, settings, spp: int) -> list[list]:
    """CPU microseconds per sample of the person's pixels grouped by the shape their camera ray hits first."""
    import mitsuba as mi

    from rh_dataset.render.focus import person_pixels, render_pixels
    from rh_dataset.render.passes import FOCUS_MARGIN, _AOV_INTEGRATOR
    from rh_dataset.render.scene import scene_dict

    s = mi.load_dict(scene_dict(scene.meshes, scene.emitter, scene.camera,
                                {"type": "path", "max_depth": int(settings.max_depth), "hide_emitters": False,
                                 **({"rr_depth": settings.rr_depth} if settings.rr_depth else {})},
                                settings.spp, pixel_format="rgba", sampler=settings.sampler))
    try:
        cov = np.array(mi.render(s, integrator=mi.load_dict(_AOV_INTEGRATOR), spp=settings.aov_spp, seed=1))[..., 3]
        pix = person_pixels(np.clip(cov, 0.0, 1.0), FOCUS_MARGIN)
        # shape_index is 0 for a miss and 1 + the shape's position in scene.shapes() for a hit (checked on the
        # scenes here: the hair's pixels sit on the head)
        first = np.array(mi.render(s, integrator=mi.load_dict({"type": "aov", "aovs": "si:shape_index"}), spp=1,
                                   seed=1))[..., -1].reshape(-1)[pix].astype(int)
        names = ["(environment)"] + [sh.id() for sh in s.shapes()]
        rows, total = [], 0.0
        for k in np.unique(first):
            sel = pix[first == k]
            if len(sel) < 100:
                continue
            render_pixels(mi, s, sel, spp, 1)  # warm-up (and the kernel, once)
            c = time.process_time()
            render_pixels(mi, s, sel, spp, 2)
            c = time.process_time() - c
            total += c
            rows.append([names[k] if k < len(names) else f"shape {k}", len(sel), len(sel) / len(pix),
                         1e6 * c / (len(sel) * spp), c])
        for row in rows:
            row.append(row[4] / total)
            del row[4]
        return rows
    finally:
        s = None


def figure(path: Path, scenes, subjects, resolution: int) -> None:
    """Head crops, old plain cut above the class's roulette, one column per subject and scene (see the docstring)."""
    from PIL import Image

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
            # the head: the top of the person's mask, a square as wide as a sixth of the frame
            ys, xs = np.nonzero(out.layers["mask"] > 0.5)
            top, side = int(ys.min()), resolution // 6
            cx = int(np.median(xs[ys < top + side // 2]))
            y0, x0 = max(top - side // 8, 0), min(max(cx - side // 2, 0), resolution - side)
            crops = [r[y0:y0 + side, x0:x0 + side] for r in rows]
            columns.append(np.concatenate(crops, axis=0))
            print(f"  {name}, subject {subject}: depth {before.max_depth} (plain) above depth {now.max_depth} "
                  f"(roulette from {now.rr_depth}); mean display value of the crop {crops[0].mean():.4f} -> "
                  f"{crops[1].mean():.4f}", flush=True)
    img = np.concatenate(columns, axis=1)
    img = np.repeat(np.repeat(img, 3, axis=0), 3, axis=1)
    Image.fromarray((np.clip(img, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)).save(path)
    print(f"wrote {path}", flush=True)


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
    p.add_argument("--skip-ab", action="store_true",
                   help="leave out the wrapper / plain / none comparison: the cost-by-first-hit table only")
    p.add_argument("--figure", type=Path, default=None, help="write the head crops (old cut / now) here instead")
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
    if args.figure is not None:
        return figure(args.figure, args.scenes, args.subjects, args.resolution)
    standard = load_presets()["standard"]
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
            if not args.skip_ab:
                bt.table(f"{title}: the strands' BSDF, medians of {args.repeats} interleaved frames",
                         ["strands", "scene load s", "beauty s", "frame CPU s", "CPU / wrapper",
                          "ops of the 2 largest kernels", "image"], ab(scene, settings, args.repeats))
            bt.table(f"{title}: cost by first hit, {args.cost_spp} spp through render_pixels",
                     ["first hit", "pixels", "share of pixels", "CPU us / sample", "share of CPU"],
                     cost_by_first_hit(scene, settings, args.cost_spp))
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end", flush=True)


if __name__ == "__main__":
    main()
