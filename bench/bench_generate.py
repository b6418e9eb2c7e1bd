"""Seconds per frame of each render preset, through the frame function `rh-generate` renders with.

    python bench/bench_generate.py [--resolution 512] [--presets draft standard reference] [--repeats 2]
    python bench/bench_generate.py --presets standard --also standard:independent:128::16   # before/after, one run
    python bench/bench_generate.py --presets draft standard --repeats 3 --distinct-frames   # new frames reuse kernels?
    python bench/bench_generate.py --presets standard --also standard:multijitter:99:4:9::d4 --repeats 3 \
        --distinct-frames --interleave                          # before / after, frames in turn (a shared machine)
    python bench/bench_generate.py --presets standard --headwear none cap brimmed_hat headscarf glasses
    python bench/bench_generate.py --protocol c --split test --resolution 128 --presets draft  # one frame, 6 views
    python bench/bench_generate.py --presets draft standard --repeats 3 --distinct-frames --subject 2  # loose

Renders frame 0 of subject 0's (or --subject's) test split of protocol a (a random pose under a random bundled HDRI,
every test layer: beauty pass + AOV pass) with `rh_dataset.generate.render_frame_to_disk`, the function the local and
Ray backends call, into a temporary folder (`--split` another split; a multi-view split's frame is every camera of it,
`protocol c`: the seconds are the frame's, all views together): the same camera fill, culling, per-split path depth
and writer as a dataset. Prints a Markdown table of each stage's median seconds. The first render of each preset
is a warm-up (JIT compilation, cached on disk afterwards) and is not timed (every row's warm-up comes before the
timed frames); the timed ones render frame 0 again, or with `--distinct-frames` frames 1, 2, ... (other poses and
lights), row by row or, with `--interleave`, in turn; building the subject is timed once. The kernel
columns (drjit's kernel history over the timed frames) say whether a frame after the first reuses its kernels:
"compiled" counts kernels not found in drjit's caches, and their code generation + backend time. --headwear: the
table again for subject 0 wearing each of the given headwear (KIND or KIND+glasses; "none" = bare-headed), same
pose, light and camera, so with/without is a ratio within one run.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

STAGES = ("pose", "light", "load", "beauty", "aov", "meta", "write")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolution", type=int, default=512,
                   help="frame width and height in pixels, in place of the protocol's (default 512)")
    p.add_argument("--presets", nargs="+", default=["draft", "standard", "reference"],
                   help="render presets timed, a table row each (rh_dataset/scenes/presets.json; default all three)")
    p.add_argument("--repeats", type=int, default=2,
                   help="timed frames per row, after its untimed warm-up; the table gives medians (default 2)")
    p.add_argument("--seed", type=int, default=0,
                   help="dataset seed (rh-generate --seed: characters, poses, lights and sampler seeds; default 0)")
    p.add_argument("--subject", type=int, default=0,
                   help="the protocol's subject rendered (default 0; seed 0's 2 wears an open jacket over a loose long "
                        "sleeve over a draped skirt, its posing several times subject 0's)")
    p.add_argument("--protocol", default="a",
                   help="protocol rendered: a, b, c, another name in rh_dataset/scenes/ or a scene JSON path "
                        "(default a)")
    p.add_argument("--split", default="test",
                   help="the protocol's split whose frame is rendered (default test; a multi-view split's frame is "
                        "every camera of it)")
    p.add_argument("--distinct-frames", action="store_true",
                   help="time frames 1..repeats of the split (each its own pose and light, as a dataset renders them) "
                        "instead of frame 0 again: the kernel columns then say whether a new frame reuses kernels")
    p.add_argument("--also", nargs="*", default=[],
                   help="extra rows preset:sampler:spp[:env_spp[:aov_spp[:aTIERS][:dDEPTH]]] (a preset with those "
                        "overrides; no or empty env_spp: every pixel at spp; aTIERS, e.g. "
                        "a16-36-64-100-169-256: samples by noise, rh_dataset.render.adaptive; dDEPTH: a fixed path "
                        "depth, no roulette, for every split), e.g. standard:independent:128::16 for the settings "
                        "before bench_sampler, standard:multijitter:99:4:9::d4 for standard's test frames before the "
                        "roulette")
    p.add_argument("--interleave", action="store_true",
                   help="time the rows' frames in turn (frame 1 of every row, then frame 2, ...) rather than row by "
                        "row, so that a load that drifts during the run falls on every row alike")
    p.add_argument("--headwear", nargs="*", default=[],
                   help="variants of subject 0's headwear, e.g. none cap brimmed_hat headscarf glasses cap+glasses")
    args = p.parse_args()
    if args.subject < 0:
        p.error(f"--subject: 0 or more, got {args.subject}")

    from rh_dataset.cli import render_settings
    from rh_dataset.generate import DatasetPlan, render_frame_to_disk, resolve_plan, subject_source
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import select_variant

    variant = select_variant(None)
    spec = load_protocol(args.protocol).with_overrides(subjects=args.subject + 1,
                                                       resolution=(args.resolution, args.resolution))
    split = spec.split(args.split)
    n_views = len(split.cameras) if split.cameras is not None else 1
    with tempfile.TemporaryDirectory(prefix="bench_generate_") as tmp:
        plan = resolve_plan(DatasetPlan(out=Path(tmp), spec=spec, settings=render_settings(args.presets[0]),
                                        seed=args.seed))
        source = subject_source(plan)
        t = time.perf_counter()
        subject = source.subject(args.subject)
        t_subject = time.perf_counter() - t
        pose = source.pose(subject, split, 0)
        shapes = source.meshes(subject, pose)
        tris = sum(len(m.faces) for m in shapes if hasattr(m, "faces"))
        strands = sum(len(m.points) for m in shapes if hasattr(m, "fibre"))
        hair = f", {strands} hair strands ({subject.character.recipe.hair.style})" if strands else ""
        print(f"machine: {platform.machine()}, {os.cpu_count()} cores, load average "
              f"{' '.join(Path('/proc/loadavg').read_text().split()[:3]) if Path('/proc/loadavg').exists() else '?'}"
              f"; Mitsuba variant {variant}; {tris} triangles before culling{hair}; {args.resolution}x{args.resolution}; "
              f"protocol {spec.protocol} {split.name} split ({split.scene_class}), {n_views} camera(s) per frame")
        print(f"subject (build character, frame camera) {t_subject:.2f} s\n")
        import drjit as dr

        dr.set_flag(dr.JitFlag.KernelHistory, True)
        print("| preset | sampler | spp | env spp | aov spp | max depth | pose+light s | scene load s | beauty s | aov s | "
              "JSON+write s | s / frame | beauty Msamples/s | kernels / frame | compiled / frame | compile s / frame |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        px = args.resolution * args.resolution
        rows = [(name, render_settings(name)) for name in args.presets]
        for item in args.also:
            pname, smp, spp, *rest = item.split(":")
            env = int(rest[0]) if rest and rest[0] else 0
            aov = int(rest[1]) if len(rest) > 1 and rest[1] else None
            tiers = next((tuple(int(v) for v in t[1:].split("-")) for t in rest[2:] if t.startswith("a")), ())
            depth = next((int(t[1:]) for t in rest[2:] if t.startswith("d")), None)
            rows.append((f"{pname} ({smp} {spp}{f' env {env}' if env else ''}{f' aov {aov}' if aov else ''}"
                         f"{' by noise ' + '-'.join(map(str, tiers)) if tiers else ''}"
                         f"{f' depth {depth}' if depth else ''})",
                         render_settings(pname, sampler=smp, spp=int(spp), env_spp=env, aov_spp=aov,
                                         adaptive_tiers=tiers, max_depth=depth)))
        variants = [(None, subject)] + [(v, _wearing(subject, v)) for v in args.headwear]
        for variant, subj in variants:
            if args.headwear:
                worn = "+".join(h.kind for h in subj.character.recipe.headwear) or "none"
                n_strands = sum(len(m.points) for m in source.meshes(subj, pose) if hasattr(m, "fibre"))
                label = f"as drawn: {worn}" if variant is None else worn
                print(f"| **headwear {label}** ({n_strands} strands) | | | | | | | | | | | | | | | |")
            subject = subj
            for name, settings in rows:  # warm-ups: each row compiles (or loads) its kernels, untimed
                render_frame_to_disk(dataclasses.replace(plan, settings=settings), source, subject, split, 0)
            dr.kernel_history()  # clears it
            runs = {name: [] for name, _ in rows}
            kernels = {name: [] for name, _ in rows}
            order = [(r, row) for r in range(args.repeats) for row in rows] if args.interleave else \
                [(r, row) for row in rows for r in range(args.repeats)]
            for r, (name, settings) in order:
                runs[name].append(render_frame_to_disk(dataclasses.replace(plan, settings=settings), source, subject,
                                                       split, r + 1 if args.distinct_frames else 0))
                kernels[name] += [k for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT]
            for name, settings in rows:
                compiled = [k for k in kernels[name] if not k.get("cache_hit")]
                compile_s = sum(k.get("codegen_time", 0.0) + k.get("backend_time", 0.0) for k in compiled) / 1000
                med = {k: float(np.median([r.seconds.get(k, 0.0) for r in runs[name]])) for k in STAGES}
                total = float(np.median([sum(r.seconds.values()) for r in runs[name]]))
                print(f"| {name} | {settings.sampler} | {settings.spp} | {settings.env_spp or '-'} | "
                      f"{settings.aov_spp} | {settings.for_split(split).max_depth} | "
                      f"{med['pose'] + med['light']:.2f} | {med['load']:.2f} | {med['beauty']:.2f} | "
                      f"{med['aov']:.2f} | {med['meta'] + med['write']:.2f} | {total:.2f} | "
                      f"{n_views * px * settings.spp / med['beauty'] / 1e6:.1f} | "
                      f"{len(kernels[name]) / args.repeats:.0f} | {len(compiled) / args.repeats:.1f} | "
                      f"{compile_s / args.repeats:.2f} |", flush=True)
            runs = runs[rows[-1][0]]
        from rh_common.imageio import read_png

        mask = read_png(runs[-1].json_path.with_name(runs[-1].json_path.stem + "_mask.png"))
        culled = runs[-1].scene_model
    print(f"\nperson coverage of the frame: {float(mask.mean()) / 255:.0%}; scene model: {culled}")


def _wearing(subject, variant: str):
    """Subject 0 with its recipe's headwear replaced ("none", "cap", "cap+glasses", ...)."""
    from rh_dataset.characters import build_character
    from rh_dataset.characters.recipe import Headwear

    kinds = [] if variant == "none" else variant.split("+")
    fabric = (0.55, 0.12, 0.1)
    hw = tuple(Headwear(k, (0.05, 0.05, 0.05) if k == "glasses" else fabric, roughness=0.3 if k == "glasses" else 0.8)
               for k in kinds)
    recipe = dataclasses.replace(subject.character.recipe, headwear=hw)
    return dataclasses.replace(subject, character=build_character(recipe), record=recipe.to_json())


if __name__ == "__main__":
    main()
