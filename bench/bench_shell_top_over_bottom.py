"""A shell top (t-shirt, long sleeve; the hoodie's trunk until 6 December, now draped cloth) over a draped bottom
(skirt, trousers, shorts) with no draped jacket or coat over both: does the bottom's cloth come out through the top when posed? Posing puts it back
under the top (character._bottoms_under_shell_top, drape.SHELL_TOPS); this bench measures the posed frames with and
without that step.

    python bench/bench_shell_top_over_bottom.py                      # seed 0's wearers, rest + 2 test poses
    python bench/bench_shell_top_over_bottom.py --subjects 23 --poses 1 --figure docs/shell_top_over_bottom.png

In: the dataset seed, the subjects (default: every benchmark subject of protocols a and b at that seed wearing a
shell top over a draped bottom and no draped jacket or coat; `sample_recipe(rng_for(seed, "character", s))`, built
as rh-generate builds them, the user's drape cache), how many test poses (`AnnySubjects.pose`, the test split's
first --poses frames) besides the rest pose. Out, printed per subject and pose, skinned (the `draft` and `standard`
presets' cloth mode), without | with the step:
  over      the bottom's vertices over the top's surface (`cloth_pose.layer_depth` < 0 within LAYER_REACH, not
            beyond the top's hem or cuffs), the farthest (mm);
  seen      of those, how many a camera sees (8 horizontal views around the subject, the ray from 2 mm off the vertex
            along its normal meeting no posed mesh; bench_cloth_pose.seen_around);
  pose s    `pose_character`'s seconds (median of --repeats);
and the totals. --figure PATH: the first subject in its first test pose, without | with, front and its left side, the
hips at 2x (render_preview: 32 spp, Open Image Denoise, a look, not a dataset frame).
The load average is printed with the times: the machine is shared.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


def wearers(seed: int) -> list[int]:
    """Seed `seed`'s benchmark subjects in a shell top over a draped bottom and no draped jacket or coat (recipes
    only: nothing is built)."""
    from subject_diversity import benchmark_recipes

    from rh_dataset.characters.drape import BOTTOMS_UNDER, SHELL_TOPS, SHELLS_UNDER
    from rh_dataset.characters.garments import garment_parts

    out = []
    for s, recipe in enumerate(benchmark_recipes("protocol_a", seed)):
        kinds = {part for g in recipe.garments for part in garment_parts(g.kind)}
        if kinds & set(SHELL_TOPS) and kinds & set(BOTTOMS_UNDER) and not kinds & set(SHELLS_UNDER):
            out.append(s)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seed", type=int, default=0, help="dataset seed whose subjects are used")
    ap.add_argument("--subjects", default="", help="comma-separated subject indices (default: every wearer)")
    ap.add_argument("--poses", type=int, default=2, help="test poses per subject besides the rest pose")
    ap.add_argument("--repeats", type=int, default=1, help="posings timed per case (the median is printed)")
    ap.add_argument("--figure", type=Path, default=None, help="write the without | with picture here")
    args = ap.parse_args(argv)
    if args.poses < 0 or args.repeats < 1:
        raise SystemExit(f"--poses: 0 or more, got {args.poses}; --repeats: 1 or more, got {args.repeats}")

    from bench_cloth_pose import rest_and_test_poses, seen_around

    from rh_dataset.characters import character as character_module
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.cloth_pose import LAYER_REACH, layer_depth
    from rh_dataset.characters.drape import BOTTOMS_UNDER, SHELL_TOPS
    from rh_dataset.cli import render_settings
    from rh_dataset.generate.plan import DatasetPlan
    from rh_dataset.generate.subjects import AnnySubjects
    from rh_dataset.spec import load_protocol

    spec = load_protocol("protocol_a")
    source = AnnySubjects(DatasetPlan(out=Path("unused"), spec=spec, settings=render_settings("standard"),
                                      seed=args.seed))
    test = next(s for s in spec.splits if s.name == "test")
    subjects = ([int(x) for x in args.subjects.split(",") if x] if args.subjects
                else wearers(args.seed))
    if not subjects:
        raise SystemExit(f"no subject of seed {args.seed} wears a shell top over a draped bottom without a jacket")
    step = character_module._bottoms_under_shell_top

    def posed_both(character, bones, root):
        out = []
        for on in (False, True):
            character_module._bottoms_under_shell_top = step if on else (lambda *a, **k: None)
            try:
                times = []
                for _ in range(args.repeats):
                    t = time.perf_counter()
                    posed = pose_character(character, bones, root)
                    times.append(time.perf_counter() - t)
            finally:
                character_module._bottoms_under_shell_top = step
            out.append((posed, float(np.median(times))))
        return out

    totals = np.zeros((2, 2), int)
    print(f"{'subject':>7s} {'pose':>10s} {'bottom':>24s} {'top':>10s}   over (farthest mm) / seen: without | with"
          f"   pose s: without | with")
    for s in subjects:
        subject = source.subject(s)
        ch = subject.character
        poses = rest_and_test_poses(source, subject, test, args.poses)
        for label, bones, root in poses:
            both = posed_both(ch, bones, root)
            cells = []
            for posed, _ in both:
                m = {x.name: x for x in posed if hasattr(x, "faces")}
                row = []
                for b in (k for k in BOTTOMS_UNDER if k in m):
                    for t in (k for k in SHELL_TOPS if k in m):
                        d = layer_depth(m[b].vertices, m[t].vertices, m[t].faces, LAYER_REACH)
                        over = np.isfinite(d) & (d < 0)
                        seen = seen_around(m[b].vertices[over], m[b].normals[over], list(m.values()))
                        far = 1e3 * float((-d[over]).max()) if over.any() else 0.0
                        row.append((b, t, int(over.sum()), far, int(seen.sum())))
                cells.append(row)
            for (b, t, o0, f0, s0), (_, _, o1, f1, s1) in zip(*cells):
                totals += [[o0, s0], [o1, s1]]
                print(f"{s:7d} {label:>10s} {b:>24s} {t:>10s}   {o0:4d} ({f0:5.1f}) / {s0:3d} | {o1:4d} ({f1:5.1f}) / "
                      f"{s1:3d}   {both[0][1]:5.2f} | {both[1][1]:5.2f}   (load {load()})", flush=True)
    print(f"total over / seen: without {totals[0, 0]} / {totals[0, 1]}, with {totals[1, 0]} / {totals[1, 1]}")

    if args.figure is not None:
        from rh_common.colourspace import quantize8, srgb_encode
        from rh_common.imageio import write_png
        from rh_dataset.characters.preview import render_preview
        from rh_dataset.poses.pose import rotation_about_z

        s = subjects[0]
        subject = source.subject(s)
        pose = source.pose(subject, test, 0)
        rows = []
        for on in (False, True):
            tiles = []
            for turn in (0.0, 90.0):
                R = rotation_about_z(turn)
                root = R if pose.root_transform is None else R @ pose.root_transform
                character_module._bottoms_under_shell_top = step if on else (lambda *a, **k: None)
                try:
                    posed = pose_character(subject.character, dict(pose.bones), root)
                finally:
                    character_module._bottoms_under_shell_top = step
                img = render_preview(posed, width=512, height=512, spp=32, seed=s, denoise=True)
                tile = quantize8(srgb_encode(np.clip(img, 0, None) * 1.3))[180:360, 128:384]
                tiles.append(np.repeat(np.repeat(tile, 2, axis=0), 2, axis=1))
            rows.append(np.concatenate(tiles, axis=1))
        write_png(args.figure, np.concatenate(rows, axis=0))
        print(f"wrote {args.figure}: subject {s}, test pose 0 ({pose.label}); rows without | with, columns front | "
              f"its left side, the hips at 2x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
