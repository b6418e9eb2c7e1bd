"""Seconds per frame and samples per second of each render preset, on one benchmark character.

    python bench/bench_generate.py [--resolution 512] [--presets draft standard reference] [--repeats 2]

Renders subject 0 of protocol a in a random test pose under a random bundled HDRI with every test layer (beauty
pass + AOV pass), at the given resolution, and prints a Markdown table. The first render of each preset is a
warm-up (JIT compilation, cached on disk afterwards) and is not timed. Character building, posing and file
writing are timed separately from rendering.
"""
from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolution", type=int, default=512)
    p.add_argument("--presets", nargs="+", default=["draft", "standard", "reference"])
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()

    from rh_dataset.characters import build_character, pose_character, sample_recipe
    from rh_common.body_model import load_anny
    from rh_dataset.generate import rng_for
    from rh_dataset.lights import build_light, bundled_hdris, mitsuba_emitter_dict, sample_light
    from rh_dataset.poses import sample_pose
    from rh_common.camera import frame_body
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import select_variant
    from rh_dataset.spec import load_presets

    variant = select_variant(None)
    t = time.perf_counter()
    recipe = sample_recipe(rng_for(args.seed, "character", 0), pool="benchmark", index=0)
    character = build_character(recipe)
    t_build = time.perf_counter() - t
    pose = sample_pose(rng_for(args.seed, "pose", 0, "test", 0), load_anny())
    t = time.perf_counter()
    meshes = pose_character(character, dict(pose.bones), pose.root_transform)
    t_pose = time.perf_counter() - t
    light = build_light(sample_light(rng_for(args.seed, "light", 0, "a", "test", 0), bundled_hdris(),
                                     allow_sunsky=False))
    lo = np.min([m.vertices.min(0) for m in meshes], 0)
    hi = np.max([m.vertices.max(0) for m in meshes], 0)
    cam = frame_body(lo, hi, args.resolution, args.resolution, 30.0)
    emitter = mitsuba_emitter_dict(light)
    layers = ["image", "mask", "albedo", "normal", "depth"]
    tris = sum(len(m.faces) for m in meshes)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; Mitsuba variant {variant}; "
          f"{tris} triangles; {args.resolution}x{args.resolution}; light {light.spec.name}")
    print(f"build_character {t_build:.2f} s, pose_character {t_pose * 1e3:.0f} ms\n")
    print("| preset | spp | aov spp | max depth | scene load s | beauty s | aov s | s / frame | beauty Msamples/s |")
    print("|---|---|---|---|---|---|---|---|---|")
    presets = load_presets()
    px = args.resolution * args.resolution
    for name in args.presets:
        pr = presets[name]
        depth = pr.depth_for("posed-envmap")  # a random test pose: protocol a's test split's scene class
        s = RenderSettings(spp=pr.spp, aov_spp=pr.aov_spp, max_depth=depth, preset=name)
        render_frame(meshes, emitter, cam, RenderSettings(spp=1, aov_spp=1, max_depth=depth), layers, 0)
        load, beauty, aov = [], [], []
        for r in range(args.repeats):
            out = render_frame(meshes, emitter, cam, s, layers, seed=r)
            load.append(out.seconds["load"])
            beauty.append(out.seconds["beauty"])
            aov.append(out.seconds["aov"])
        lo_, b, a = (float(np.median(x)) for x in (load, beauty, aov))
        print(f"| {name} | {pr.spp} | {pr.aov_spp} | {depth} | {lo_:.2f} | {b:.2f} | {a:.2f} | "
              f"{lo_ + b + a:.2f} | {px * pr.spp / b / 1e6:.1f} |", flush=True)
    print(f"\nperson coverage of the frame: {float(out.layers['mask'].mean()):.0%}")


if __name__ == "__main__":
    main()
