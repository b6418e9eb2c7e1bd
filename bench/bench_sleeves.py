"""The draped sleeves (`draped_sleeves`, `draped_long_sleeves`, `draped_hoodie_sleeves`, `draped_coat_sleeves`:
rh_dataset/characters/sleeves.py) on the generator's own subjects: what they cost, and whether they stay clear of the
arm, of themselves and of the shell sleeve under them.

    python bench/bench_sleeves.py                          # seed 0's loose t-shirt wearers, rest + 2 test poses
    python bench/bench_sleeves.py --kind draped_long_sleeves   # the loose long sleeve's wearers
    python bench/bench_sleeves.py --kind draped_hoodie_sleeves # the hoodie's
    python bench/bench_sleeves.py --kind draped_coat_sleeves   # the open coat's and jacket's (over a top's shell)
    python bench/bench_sleeves.py --subjects 3 --poses 1 --figure after.png --before before.png

In: the sleeves' kind (--kind), the dataset seed, the subjects (default: every benchmark subject of protocols a and b
at that seed wearing a garment of that kind (the loose t-shirt, the loose long sleeve, the hoodie, the open coat or
jacket) with no open jacket or coat over it; built as rh-generate builds them, full drapes, the user's drape cache),
how many test poses (`AnnySubjects.pose`, the test split's first --poses frames) besides the rest pose.
Out, printed per subject: the sleeves' drape seconds (simulated afresh, the cache not read), their pinned rings'
places along the upper arms (cm from the shoulder joint) and their hems'; then per pose (skinned, the `draft` and
`standard` presets' cloth mode, and simulated: the sleeves are skinned in both):
  depth     the sleeves' deepest vertex under the skin (mm, > 0 inside; `drape.penetration`);
  cross     the sleeves' self-crossing edges (`cloth_pose.self_crossings`), and how many of their crossing points
            (`cloth_pose.crossing_points`, one per edge and triangle it passes through) a camera sees from either
            side of the triangle (8 horizontal views, `bench_cloth_pose.seen_around`: nothing between the point,
            2 mm off the triangle, and the camera);
  shell out the shell's ("tee", "longtop", "hoodie", "coat") sleeve vertices (on the upper arm or forearm) within 2 cm
            of the sleeves lying over them (`cloth_pose.layer_depth` < 0),
            the worst (mm) and how many a camera sees (8 horizontal views, `bench_cloth_pose.seen_around`): the shell's
            sleeve ends under the cloth's pinned ring and must stay inside the cloth;
  slot      the pinned rings' height over the shell under them (median and largest, mm): a wide slot shows as a dark
            line round the top of the sleeve;
  pose s    `pose_character`'s seconds (median of 3; skinned: beside it, the same character without the sleeves'
            part, posed in turn);
  under out the shells of other garments (the top's sleeve under the open coat's) on the upper arm or forearm lying
            over the sleeves (`layer_depth` < 0): how many vertices, the worst (mm) and how many a camera sees.
--figure PATH: the first subject at rest and in its first test pose, front and from its left, shoulders at 2x
(render_preview: 32 spp, Open Image Denoise, a look, not a dataset frame), one row; --before PNG: a row this script
wrote in another checkout (there, shell sleeves), put above it. To run the rules of another commit, copy this script
into a checkout of it, with bench_cloth_pose.py (its arguments and subjects), and run it there (sys.path takes the
script's own checkout). The load average is printed.
"""
from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


# The garments each sleeves' kind belongs to, and the shell under its sleeves' rings (the open jacket is the coat cut
# short and wears the coat's sleeves).
TOPS = {"draped_sleeves": (("draped_tshirt",), "tee"), "draped_long_sleeves": (("draped_longsleeve",), "longtop"),
        "draped_hoodie_sleeves": (("draped_hoodie",), "hoodie"),
        "draped_coat_sleeves": (("draped_coat", "draped_jacket"), "coat")}
OUTERWEAR = {"draped_jacket", "draped_coat"}


def wearers(seed: int, kind: str = "draped_sleeves") -> list[int]:
    """Seed `seed`'s benchmark subjects in a garment whose sleeves are `kind`, with no open jacket or coat over it
    (recipes only)."""
    from subject_diversity import benchmark_recipes

    garments = set(TOPS[kind][0])
    return [s for s, r in enumerate(benchmark_recipes("protocol_a", seed))
            if garments & (kinds := {g.kind for g in r.garments})
            and (garments <= OUTERWEAR or not OUTERWEAR & kinds)]


def main(argv: list[str] | None = None) -> int:
    from bench_cloth_pose import rest_and_test_poses, seen_around, subject_bench_args, test_source

    args = subject_bench_args(__doc__, argv, lambda ap: ap.add_argument(
        "--kind", default="draped_sleeves", choices=sorted(TOPS), help="the sleeves measured (default: the short)"))
    kind, shell_name = args.kind, TOPS[args.kind][1]

    from rh_common.body_model import ANNY_TOPOLOGY
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.body_features import group_mask
    from rh_dataset.characters.cloth_pose import crossing_points, layer_depth, self_crossings
    from rh_dataset.characters.drape import penetration

    source, test = test_source(args.seed)
    subjects = [int(x) for x in args.subjects.split(",") if x] if args.subjects else wearers(args.seed, kind)
    if not subjects:
        raise SystemExit(f"no subject of seed {args.seed} wears a {' or '.join(TOPS[kind][0])} "
                         "without a jacket or coat over it")
    try:
        from rh_dataset.characters.drape import drape_garment, drape_settings
        from rh_dataset.characters.sleeves import SIDES, SLEEVE_CUTS, sleeve_pattern, sleeve_tops
    except ImportError:  # a checkout before the draped sleeves: only the figure and the timing
        drape_garment = None
    print(f"{'subject':>7s} {'pose':>12s} {'mode':>9s}   depth mm  cross  seen   shell out: n  worst mm  seen   "
          f"slot mm: median  max   pose s | without   under out: n  worst mm  seen")
    t0 = time.perf_counter()
    for s in subjects:
        subject = source.subject(s)
        ch = subject.character
        names = [p.name for p in ch.parts]
        if drape_garment is not None and kind in names:
            st = drape_settings(kind, "full")
            t = time.perf_counter()
            drape_garment(kind, ch.phenotype, st, use_cache=False)
            secs = time.perf_counter() - t
            tops = sleeve_tops(ch.phenotype, st.n_around, SLEEVE_CUTS[kind])
            # Each tube's length, ring centre to ring centre, from the pinned ring to the hem, plus the ring's place.
            v, _, _, _, _, pieces = sleeve_pattern(ch.phenotype, st.n_around, st.n_rings, SLEEVE_CUTS[kind])
            reach = {side: tops[side] + float(np.linalg.norm(np.diff(v[g].mean(1), axis=0), axis=1).sum())
                     for side, g in zip(SIDES, pieces)}
            print(f"{s:7d} sleeves drape {secs:.1f} s (uncached, full); rings at "
                  + ", ".join(f"{side} {100 * tops[side]:.1f} cm" for side in SIDES) + "; hems at "
                  + ", ".join(f"{side} {100 * reach[side]:.1f} cm" for side in SIDES) + f"   (load {load()})",
                  flush=True)
        # The same character without its sleeves' part (the shell's sleeves as cut for them), timed beside it.
        without = (dataclasses.replace(ch, parts=[p for p in ch.parts if p.name != kind])
                   if kind in names else None)
        arm_mask = group_mask(ANNY_TOPOLOGY, "upperarm", "lowerarm")
        on_arm = arm_mask[ch.part(shell_name).body_vertex] if shell_name in names else None
        # Shells of other garments on the arm (the top's sleeve under the coat's sleeves): they must stay inside.
        inner = {p.name: arm_mask[p.body_vertex] for p in ch.parts
                 if p.name not in (kind, shell_name, "body") and p.body_faces is not None
                 and arm_mask[p.body_vertex].any()}
        for label, bones, root in rest_and_test_poses(source, subject, test, args.poses):
            for mode in ("skinned", "simulated"):
                posed, secs, bare = None, [], []
                for _ in range(3 if mode == "skinned" else 1):
                    t = time.perf_counter()
                    posed = pose_character(ch, bones, root, cloth=mode)
                    secs.append(time.perf_counter() - t)
                    if without is not None and mode == "skinned":
                        t = time.perf_counter()
                        pose_character(without, bones, root, cloth=mode)
                        bare.append(time.perf_counter() - t)
                plain = f"{np.median(bare):5.2f}" if bare else "    -"
                by = {m.name: m for m in posed if hasattr(m, "faces")}
                if kind not in by:
                    print(f"{s:7d} {label:>12s} {mode:>9s}   (no draped sleeves)   pose s {np.median(secs):5.2f}")
                    continue
                sl, tee, body = by[kind], by[shell_name], by["body"]
                v = np.asarray(sl.vertices, np.float64)
                depth = 1e3 * float(penetration(np.asarray(body.vertices, np.float64), body.faces, v).max())
                cross = self_crossings(v, sl.faces)
                cp, cn = crossing_points(v, sl.faces)
                # Either side of the pierced triangle, in one scene: the points twice, the normals both ways.
                both = seen_around(np.r_[cp, cp], np.r_[cn, -cn], list(by.values())).reshape(2, -1)
                cross_seen = int(both.any(0).sum())
                tv = np.asarray(tee.vertices, np.float64)
                d = np.where(on_arm, layer_depth(tv, v, sl.faces), np.nan)  # the shell's sleeves, not its trunk
                out = np.flatnonzero(np.nan_to_num(d, nan=1.0) < 0)
                seen = int(seen_around(tv[out], np.asarray(tee.normals, np.float64)[out], list(by.values())).sum())
                worst = -1e3 * float(d[out].min()) if len(out) else 0.0
                ring = ring_vertices(ch.phenotype, kind)
                h = -layer_depth(v[ring], tv, tee.faces, near=0.03)
                h = h[np.isfinite(h)]
                slot = (1e3 * float(np.median(h)), 1e3 * float(h.max())) if len(h) else (np.nan, np.nan)
                n_in, worst_in, seen_in = 0, 0.0, 0
                for name, mask in inner.items():
                    iv = np.asarray(by[name].vertices, np.float64)
                    di = np.where(mask, layer_depth(iv, v, sl.faces), np.nan)
                    o = np.flatnonzero(np.nan_to_num(di, nan=1.0) < 0)
                    n_in += len(o)
                    worst_in = max(worst_in, -1e3 * float(di[o].min()) if len(o) else 0.0)
                    seen_in += int(seen_around(iv[o], np.asarray(by[name].normals, np.float64)[o],
                                               list(by.values())).sum())
                print(f"{s:7d} {label:>12s} {mode:>9s}   {depth:8.2f} {cross:6d} {cross_seen:5d}   {len(out):12d} "
                      f"{worst:9.2f} "
                      f"{seen:5d}   {slot[0]:14.1f} {slot[1]:5.1f}   {np.median(secs):6.2f} | {plain}   "
                      f"{n_in:10d} {worst_in:9.2f} {seen_in:5d}   (load {load()})",
                      flush=True)
    print(f"{len(subjects)} subjects, {time.perf_counter() - t0:.0f} s (load {load()})")
    if args.figure is not None:
        figure(source, test, subjects[0], args.figure, args.before)
    return 0


def ring_vertices(phenotype, kind: str = "draped_sleeves") -> np.ndarray:
    """The sleeves' render-mesh vertices on their pinned rings (`sleeves_render_mesh` maps render vertices to the
    drape's particles, whose `pinned` marks the rings)."""
    from rh_dataset.characters.drape import drape_garment, drape_settings
    from rh_dataset.characters.sleeves import sleeves_render_mesh

    g = drape_garment(kind, phenotype, drape_settings(kind, "full"))
    src = sleeves_render_mesh(g.pattern, g.pieces)[0]
    return np.flatnonzero(np.asarray(g.pinned, bool)[src])


def figure(source, test, s: int, path: Path, before: Path | None) -> None:
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import read_png, write_png
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.preview import render_preview
    from rh_dataset.poses.pose import rotation_about_z

    subject = source.subject(s)
    pose = source.pose(subject, test, 0)
    tiles = []
    for bones, base in ((None, None), (dict(pose.bones), pose.root_transform)):
        for turn in (0.0, 90.0):
            R = rotation_about_z(turn)
            root = R if base is None else R @ base
            posed = pose_character(subject.character, bones, root)
            img = render_preview(posed, width=512, height=512, spp=32, seed=s, denoise=True)
            tile = quantize8(srgb_encode(np.clip(img, 0, None) * 1.3))[50:250, 96:416]
            tiles.append(np.repeat(np.repeat(tile, 2, axis=0), 2, axis=1))
    row = np.concatenate(tiles, axis=1)
    if before is not None:
        above = read_png(before)
        if above.shape != row.shape:
            raise SystemExit(f"--before {before}: {above.shape}, not a row of this script ({row.shape})")
        row = np.concatenate([above, row], axis=0)
    write_png(path, row)
    print(f"wrote {path}: subject {s}, rest | test pose 0 ({pose.label}); front | left, shoulders at 2x"
          + ("; above: --before" if before is not None else ""))


if __name__ == "__main__":
    raise SystemExit(main())
