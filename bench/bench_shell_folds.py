"""Shells folded over where they are lifted over draped cloth: a shell top over a draped bottom's waistband, which
stands 1-3 cm off the skin at the hips and bridges the hollow of the back. A shell vertex sits out along the body's
normal by its offset (`garments._shell`), and where neighbouring offsets differ by centimetres, or the body is
concave under a large one, its triangles turn over: in renders, grey facets above the top's hem (benchmark subject
8, docs/SUBJECTS.md). Since 5 December, afternoon, the cloth lifts the layers over it by `drape.layer_lift` (before,
each cloth vertex lifted only its nearest body vertex), and a lifted shell vertex's offset direction turns to the
smoothed body normals (`character._lift_weight`).

    python bench/bench_shell_folds.py                     # seed 0's wearers, rest + 2 test poses
    python bench/bench_shell_folds.py --subjects 8 --poses 1
    python bench/bench_shell_folds.py --subjects 1 --poses 1 --figure after.png --before before.png

In: the dataset seed, the subjects (default: every benchmark subject of protocols a and b at that seed wearing a
shell top over a draped bottom; built as rh-generate builds them, the user's drape cache), how many test poses
(`AnnySubjects.pose`, the test split's first --poses frames) besides the rest pose. Out, printed per subject, pose and
shell top (skinned, the `draft` and `standard` presets' cloth mode):
  folded    the shell's triangles whose geometric normal points against their shading normal (the mean of their
            corners' posed body normals, as rendered), their area (cm^2), and how many of their centroids a camera
            sees (8 horizontal views around the subject: bench_cloth_pose.seen_around);
  lifted    of those, the triangles with a corner lifted over the cloth (offset more than 2 mm over its garment's
            own, garments.BASE_OFFSET), and how many of them are seen; the rest fold where the pose bends the shell
            (armpits, elbows), as every shell's may;
  step      the largest offset difference between two corners of one of its triangles (mm), and its largest offset;
  pose s    `pose_character`'s seconds, median of 3, and the same without turning the lifted vertices' offset
            direction (`character._lift_weight` patched to None; since 5 December, afternoon; older checkouts: "-");
and the totals. --figure PATH: the first subject in its first test pose, front and back, the hips at 2x
(render_preview: 32 spp, Open Image Denoise, a look, not a dataset frame), one row; --before PNG: a row this script
wrote in another checkout, put above it. To compare with the rules before, copy this script and
bench_cloth_pose.py (its arguments and subjects) into a checkout of that commit and run it there (sys.path takes the
script's own checkout). The load average is printed: the machine is shared.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


def wearers(seed: int) -> list[int]:
    """Seed `seed`'s benchmark subjects in a shell top over a draped bottom, jacket or not (recipes only)."""
    from subject_diversity import benchmark_recipes

    from rh_dataset.characters.drape import BOTTOMS_UNDER, SHELL_TOPS
    from rh_dataset.characters.garments import garment_parts

    out = []
    for s, recipe in enumerate(benchmark_recipes("protocol_a", seed)):
        kinds = {part for g in recipe.garments for part in garment_parts(g.kind)}
        if kinds & set(SHELL_TOPS) and kinds & set(BOTTOMS_UNDER):
            out.append(s)
    return out


def timed(fn):
    """(fn's result, the median of 3 calls' seconds)."""
    out, secs = None, []
    for _ in range(3):
        t = time.perf_counter()
        out = fn()
        secs.append(time.perf_counter() - t)
    return out, float(np.median(secs))


def folded(mesh) -> np.ndarray:
    """(F,) bool: the posed mesh's triangles turned over (geometric normal against the mean shading normal)."""
    v = np.asarray(mesh.vertices, np.float64)
    f = np.asarray(mesh.faces)
    g = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return (g * np.asarray(mesh.normals, np.float64)[f].sum(1)).sum(1) < 0


def main(argv: list[str] | None = None) -> int:
    from bench_cloth_pose import rest_and_test_poses, seen_around, subject_bench_args, test_source

    args = subject_bench_args(__doc__, argv)

    from rh_dataset.characters import character as character_module
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.drape import SHELL_TOPS
    from rh_dataset.characters.garments import BASE_OFFSET

    source, test = test_source(args.seed)
    subjects = [int(x) for x in args.subjects.split(",") if x] if args.subjects else wearers(args.seed)
    if not subjects:
        raise SystemExit(f"no subject of seed {args.seed} wears a shell top over a draped bottom")
    total = np.zeros(5)
    print(f"{'subject':>7s} {'pose':>12s} {'top':>10s}   folded: faces   cm^2  seen   lifted: faces  seen   "
          f"step mm  most mm   pose s: as is | no turn")
    t0 = time.perf_counter()
    for s in subjects:
        subject = source.subject(s)
        ch = subject.character
        poses = rest_and_test_poses(source, subject, test, args.poses)
        for label, bones, root in poses:
            posed, secs = timed(lambda: pose_character(ch, bones, root))
            plain = "-"
            if hasattr(character_module, "_lift_weight"):
                turn = character_module._lift_weight
                character_module._lift_weight = lambda part: None
                try:
                    plain = f"{timed(lambda: pose_character(ch, bones, root))[1]:5.2f}"
                finally:
                    character_module._lift_weight = turn
            meshes = [m for m in posed if hasattr(m, "faces")]
            for m in (m for m in meshes if m.name in SHELL_TOPS):
                part = ch.part(m.name)
                bad = folded(m)
                v = np.asarray(m.vertices, np.float64)
                f = np.asarray(m.faces)[bad]
                area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()
                n = np.asarray(m.normals, np.float64)[f].mean(1)
                n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
                seen = seen_around(v[f].mean(1), n, meshes)
                off = part.offset[np.asarray(m.faces)]
                step = 1e3 * float((off.max(1) - off.min(1)).max())
                lifted = off[bad].max(1) > BASE_OFFSET[m.name] + 0.002
                row = [bad.sum(), 1e4 * area, seen.sum(), lifted.sum(), (seen & lifted).sum()]
                total += row
                print(f"{s:7d} {label:>12s} {m.name:>10s}   {row[0]:13d} {row[1]:6.1f} {row[2]:5d}   {row[3]:13d} "
                      f"{row[4]:5d}   {step:7.1f} {1e3 * float(part.offset.max()):8.1f}   {secs:5.2f} | {plain:>5s}   "
                      f"(load {load()})", flush=True)
    print(f"total folded: {int(total[0])} faces, {total[1]:.1f} cm^2, {int(total[2])} seen; lifted {int(total[3])}, "
          f"{int(total[4])} seen ({len(subjects)} subjects, {time.perf_counter() - t0:.0f} s, load {load()})")
    if args.figure is not None:
        from rh_common.colourspace import quantize8, srgb_encode
        from rh_common.imageio import read_png, write_png
        from rh_dataset.characters.preview import render_preview
        from rh_dataset.poses.pose import rotation_about_z

        s = subjects[0]
        subject = source.subject(s)
        pose = source.pose(subject, test, 0)
        tiles = []
        for turn in (0.0, 180.0):
            R = rotation_about_z(turn)
            root = R if pose.root_transform is None else R @ pose.root_transform
            posed = pose_character(subject.character, dict(pose.bones), root)
            img = render_preview(posed, width=512, height=512, spp=32, seed=s, denoise=True)
            tile = quantize8(srgb_encode(np.clip(img, 0, None) * 1.3))[170:330, 128:384]
            tiles.append(np.repeat(np.repeat(tile, 2, axis=0), 2, axis=1))
        row = np.concatenate(tiles, axis=1)
        if args.before is not None:
            above = read_png(args.before)
            if above.shape != row.shape:
                raise SystemExit(f"--before {args.before}: {above.shape}, not a row of this script ({row.shape})")
            row = np.concatenate([above, row], axis=0)
        write_png(args.figure, row)
        print(f"wrote {args.figure}: subject {s}, test pose 0 ({pose.label}); front | back, the hips at 2x"
              + ("; above: --before" if args.before is not None else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
