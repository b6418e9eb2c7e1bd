"""The coat's shell (worn under an open jacket's or a coat's panels) against those panels, for the generator's own
subjects at rest: does any of its vertices under the panels' pinned ring stand outside them?

    python bench/bench_coat_shell.py                                 # seed 0's jackets and coats over loose tops
    python bench/bench_coat_shell.py --subjects 7,19,25,30          # ... over shell tops
    python bench/bench_coat_shell.py --drape coarse --subjects 14,26

Subjects are rh-generate's (`sample_recipe(rng_for(seed, "character", s))`, benchmark pool), built as the generator
builds them (the user's drape cache: a cold one simulates each drape, minutes at `full`). Per subject: the shell's
trunk vertices under the pinned ring in anny's rest A-pose, but for the open front's 4 cm either side of the middle
(`bench_cloth.coat_overlap`); how many of them lie outside the panels (`cloth_pose.layer_depth` < 0); the least
depth under the panels (negative: the worst poke out); the shell's largest offset off the skin. Over a loose top the
shell is lifted over the top's cloth (`garments._shell`'s `under`) and, before `garments._under_cover`, came out
through the panels under their ring.
Then the slot: how far the panels' pinned ring stands off the shell under it (each ring vertex's height over the
shell, `layer_depth` against the shell, within 3 cm): its median and largest. Seen from above (a bending pose) a wide
slot shows as a dark line across the chest; the loose t-shirt's ring was brought to 2.5 mm over its shell for that
(docs/ARCHITECTURE.md, "The loose t-shirt").
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", default="2,14,21,26,40,41,45,48",
                    help="comma-separated benchmark subjects (rh-generate's, at --seed) wearing an open jacket or a "
                         "coat")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the recipes come from")
    ap.add_argument("--drape", default="full", choices=("full", "coarse"), help="drape level (RenderSettings.drape)")
    args = ap.parse_args(argv)

    from bench_cloth import coat_overlap
    from rh_dataset.characters import build_character, pose_character, sample_recipe
    from rh_dataset.characters.cloth_pose import layer_depth
    from rh_dataset.characters.drape import drape_layers
    from rh_dataset.generate import rng_for

    print(f"load average at start: {' '.join(open('/proc/loadavg').read().split()[:3])}; drape {args.drape}")
    for s in (int(x) for x in args.subjects.split(",")):
        recipe = sample_recipe(rng_for(args.seed, "character", s), pool="benchmark", index=s)
        kinds = [g.kind for g in recipe.garments]
        kind = next((k for k in kinds if k in ("draped_jacket", "draped_coat")), None)
        if kind is None:
            ap.error(f"benchmark subject {s} wears no open jacket or coat: {kinds}")
        t0 = time.perf_counter()
        ch = build_character(recipe, 64, drape=args.drape)
        g = drape_layers(kinds, recipe.phenotype, args.drape)[kind]  # as the build drapes it (cached by it)
        low = coat_overlap(ch, float(g.vertices[g.pinned, 2].mean()))
        rest = {m.name: m for m in pose_character(ch, {})}
        shell_v, shell_f = rest["coat"].vertices.astype(np.float64), rest["coat"].faces
        d = layer_depth(shell_v[low], rest[kind].vertices.astype(np.float64), rest[kind].faces)
        slot = -layer_depth(rest[kind].vertices[g.pinned].astype(np.float64), shell_v, shell_f)
        print(f"subject {s:2d} {', '.join(kinds)}: {int(low.sum())} shell vertices under the ring, "
              f"{int((d < 0).sum())} outside the panels, the least {1e3 * float(np.nanmin(d)):.2f} mm under them; "
              f"shell offset up to {1e3 * float(ch.part('coat').offset.max()):.1f} mm; the ring over the shell "
              f"{1e3 * float(np.nanmedian(slot)):.1f} mm (median), {1e3 * float(np.nanmax(slot)):.1f} mm at most "
              f"({int(np.isfinite(slot).sum())} of {int(g.pinned.sum())} ring vertices over it)"
              f" ({time.perf_counter() - t0:.0f} s, load "
              f"{open('/proc/loadavg').read().split()[0]})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
