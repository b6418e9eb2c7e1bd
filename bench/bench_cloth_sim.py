"""The per-frame cloth simulation's own settings (`cloth_pose.ClothPoseSettings`): what each costs in seconds and what
it changes in the cloth, on frames the "auto" cloth mode simulates.

    python bench/bench_cloth_sim.py                                    # subject 29's and subject 0's sits
    python bench/bench_cloth_sim.py --cases 35:0 --variants iterations=7 settle_steps=15
    python bench/bench_cloth_sim.py --cases 9:3 --variants                 # the settings as they are only

In: benchmark subjects of --seed as rh-generate draws them (`sample_recipe(rng_for(seed, "character", s))`), built at
the `full` drape (the user's drape cache; a cold one drapes first), and their test poses (`sample_pose(rng_for(seed,
"pose", s, "test", j))`); --cases lists subject:pose. Out: one line per (case, setting), the settings as they are
first (the reference the others are measured against), then each --variants setting (field=value of
ClothPoseSettings, one field each); before them, for scale, the frame's stretch and self-crossings as posed skinned
(`pose_character` with "skinned": what the "auto" mode weighs):
  wall s / cpu s  `cloth_pose.simulated_parts` (the whole per-frame simulation, the body's motion included; the
                  process's CPU time: Warp runs its CPU kernels on one core);
  steps           the simulation's move + settle steps;
  stretch         per simulated part, the share of its edges past `cloth_pose.STRETCH_LIMIT` against its drape
                  (`overstretched`, the "auto" mode's measure; the fabric's own give is a few per cent);
  self            per part, its edges through its own triangles (`cloth_pose.self_crossings`);
  from reference  per part, the mean and largest vertex distance (mm) to the reference settings' cloth.
The load average is printed with every line: the machine may be shared. Nothing here is rendered.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

DEFAULT_VARIANTS = ("iterations=7", "iterations=5", "settle_steps=15", "max_body_step=0.0075")


def parse_variant(text: str) -> dict:
    """"field=value" -> {field: value} for one ClothPoseSettings field (its type taken from the default)."""
    from rh_dataset.characters.cloth_pose import ClothPoseSettings

    name, sep, value = text.partition("=")
    fields = {f.name: f for f in dataclasses.fields(ClothPoseSettings)}
    if not sep or name not in fields:
        raise ValueError(f"--variants: {text!r} is not field=value of ClothPoseSettings ({', '.join(fields)})")
    kind = type(getattr(ClothPoseSettings(), name))
    try:
        return {name: kind(value)}
    except ValueError:
        raise ValueError(f"--variants: {text!r}: {name} takes a{'n integer' if kind is int else ' number'}") from None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--cases", default="29:7,0:2",
                    help="comma-separated subject:test-pose pairs (default 29:7,0:2: two sits 'auto' simulates)")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the subjects and poses come from")
    ap.add_argument("--variants", nargs="*", default=list(DEFAULT_VARIANTS),
                    help="ClothPoseSettings fields to change, one per run, as field=value "
                         f"(default: {' '.join(DEFAULT_VARIANTS)}; given empty: the settings as they are only)")
    args = ap.parse_args(argv)
    try:
        cases = [tuple(int(x) for x in c.split(":")) for c in args.cases.split(",")]
        if any(len(c) != 2 for c in cases):
            raise ValueError
    except ValueError:
        ap.error(f"--cases must be subject:pose pairs, got {args.cases!r}")
    try:
        variants = [parse_variant(v) for v in args.variants]
    except ValueError as e:
        ap.error(str(e))

    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character, sample_recipe
    from rh_dataset.characters.cloth_pose import (SIMULATED_KINDS, ClothPoseSettings, overstretched, self_crossings,
                                                  simulated_parts)
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose

    def load() -> str:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())

    print(f"load average at start: {load()}; reference: {ClothPoseSettings()}")
    for s, j in cases:
        recipe = sample_recipe(rng_for(args.seed, "character", s), pool="benchmark", index=s)
        ch = build_character(recipe, 64, drape="full")
        pose = sample_pose(rng_for(args.seed, "pose", s, "test", j), load_anny())
        parts = [p for p in ch.parts if p.name in SIMULATED_KINDS]
        if not parts:
            print(f"subject {s}: wears no simulated draped part; skipped")
            continue
        # the same frame skinned (as posed by pose_character: what "auto" weighs), for scale
        skinned = {m.name: m.vertices for m in pose_character(ch, dict(pose.bones), pose.root_transform, "skinned")
                   if m.name in {p.name for p in parts}}
        print(f"subject {s} test {j} ({pose.label}) {'skinned':22s} " + "; ".join(
            f"{p.name}: stretch {100 * overstretched(p.skinning.bind, skinned[p.name], p.faces):4.1f} %, "
            f"self {self_crossings(skinned[p.name], p.faces):3d}" for p in parts), flush=True)
        reference = None
        for change in [{}] + variants:
            stats: dict = {}
            t0, c0 = time.perf_counter(), time.process_time()
            out = simulated_parts(ch, dict(pose.bones), dataclasses.replace(ClothPoseSettings(), **change), stats)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            cells = []
            for p in parts:
                cell = (f"{p.name}: stretch {100 * overstretched(p.skinning.bind, out[p.name], p.faces):4.1f} %, "
                        f"self {self_crossings(out[p.name], p.faces):3d}")
                if reference is not None:
                    d = 1e3 * np.linalg.norm(out[p.name] - reference[p.name], axis=1)
                    cell += f", from reference {d.mean():5.1f} mm mean, {d.max():5.1f} max"
                cells.append(cell)
            reference = out if reference is None else reference
            label = ", ".join(f"{k}={v}" for k, v in change.items()) or "reference"
            print(f"subject {s} test {j} ({pose.label}) {label:22s} {wall:6.1f} s wall, {cpu:6.1f} s cpu, steps "
                  f"{stats['move_steps']} + {stats['settle_steps']}; {'; '.join(cells)}  (load {load()})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
