"""Skin a camera sees through draped cloth, counted in pixels: the image-space check of issue 17's "no cloth passes
through the body visibly"; and, per frame, how the "auto" cloth mode posed it.

    python bench/skin_seen.py --subjects 14,18 --poses 3 [--size 512] [--views 4] [--tuck-depth M]
                               [--cloth skinned|simulated|auto] [--no-render] [--figure out.png]
                               [--stretch-by-kind] [--stretch-figure out.png [--figure-above S]]

In: seed `--seed`'s benchmark subjects (protocol a's test split, built as at the `standard` preset: full drapes) and
their first `--poses` test poses, posed as `rh-generate` poses them with `--cloth`. Out, per frame: the mode the cloth
took ("auto" picks per frame), the skin vertices still out through the cloth after posing (`character.skin_out_count`:
through the kinds the simulation poses, `cloth_pose.SIMULATED_KINDS`, what "auto" weighs; and through all the draped
parts, the draped sleeves too), the share of a skirt's or dress's edges stretched past `cloth_pose.STRETCH_LIMIT`
(`character.cloth_stretch`, "auto"'s other measure; for an "auto" frame also the skinned share that decided it) and
the posing's seconds. Then, unless `--no-render`: the body's faces that lie inside a
draped garment at rest (each draped part's `covered_skin`) are coloured: green where a corner came out through the posed
cloth (`cloth_pose.skin_out` within `bench_cloth_pose.THROUGH_REACH`, the `through` of bench_cloth_pose.py), blue where
all lie under it still. The posed character's albedo AOV is rendered (`preview.render_preview`, 4 spp) from `--views`
directions around it (the posed character turned about the vertical), twice with the same samples: those colours, then
black. Out: the body faces through, per view and in all the pixels where at least a quarter of the samples saw each kind
(the green, resp. blue, difference of the two renders), whatever the garments' own colours, the pixels that saw the
character at all, then (skinned only) the body vertices the tuck moved and `pose_character`'s seconds with and without
it (`tuck_stats`); the rest pose first as the check (none through, none tucked expected). At the end, the posed frames
by the mode their cloth took (`print_modes`) and summed by pose label (`print_by_label`). Which faces are coloured is
decided on anny's posed body; the render shows the body as posing leaves it, its skin out through the cloth tucked
`--tuck-depth` under it (`cloth_pose.tuck_skin`; 0: as the cloth leaves it), so green pixels are skin the tuck left out,
or skin seen through a gap. Blue pixels are skin seen from under the cloth: through a hem, a cuff or a neckline
(legitimately), or through gaps where the skinned cloth folds through itself. Skin under shell garments is culled by the
renderer and not counted. `bench_cloth_pose.py`'s `seen_around` says which vertices could be seen (a ray to 8 cameras);
this says how many pixels are. `--figure`: the posed frame and view with the most green pixels, those ringed in magenta
and the blue ones in cyan. `--stretch-by-kind`: every draped kind's stretched share too, summed by kind and pose label,
and how many frames "auto" would add if it weighed each simulated kind as it weighs skirts and dresses.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

SHARE = 0.25  # a pixel counts when at least this share of its samples saw the skin


class PosedFrame(NamedTuple):
    """One posed frame's row: what `print_modes` and `print_by_label` sum."""

    subject: int
    label: str
    counts: list  # per view: (pixels of skin through the cloth, other skin from under it, the character's pixels)
    mode: str  # how its cloth was posed
    skin_out: int  # skin vertices out through the simulated kinds, as posed
    posing_s: float
    skin_out_all: int  # ... through every draped part
    stretched: float  # the skirts' and dresses' share of edges past STRETCH_LIMIT, as posed
    skin_out_skinned: int  # "auto": the skinned count it chose by (else skin_out)
    stretched_skinned: float  # "auto": the skinned share it chose by (else stretched)
    auto: bool  # "auto" chose the mode
    by_kind: dict = {}  # --stretch-by-kind: each draped part's share of edges past STRETCH_LIMIT, as posed


def covered_skin(character) -> dict[str, np.ndarray]:
    """{draped part: anny body vertex indices inside it at rest}: the part's `covered_skin` (`cloth_pose.skin_inside`
    of the cloth as posing leaves it at rest; a lifted part's `inside_skin`)."""
    return {p.name: p.covered_skin for p in character.parts if p.covered_skin is not None}


def under_faces(covered: dict[str, np.ndarray]) -> np.ndarray:
    """(F,) bool over anny's body faces whose three corners lie inside some draped part at rest."""
    from rh_dataset.characters.body import body_topology

    faces = body_topology().faces
    inside = np.zeros(int(faces.max()) + 1, bool)
    for v in covered.values():
        inside[v] = True
    return inside[faces].all(axis=1)


def through_faces(character, bones, root, posed: list, covered: dict[str, np.ndarray]) -> np.ndarray:
    """(F,) bool over anny's body faces (the render mesh's, in the same order) with a corner that lies inside a
    draped part at rest and outside its posed surface (in `posed`) now (`cloth_pose.skin_out` within
    bench_cloth_pose's THROUGH_REACH), on anny's posed body, before the tuck: skin come out through it."""
    from bench_cloth_pose import THROUGH_REACH

    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.cloth_pose import skin_out

    faces = body_topology().faces
    body = run_anny(character.phenotype, bones)["vertices"]
    if root is not None:
        body = body @ np.asarray(root)[:3, :3].T + np.asarray(root)[:3, 3]
    out = np.zeros(len(body), bool)
    for part in character.parts:
        inside = covered.get(part.name)
        if inside is None or not len(inside):
            continue
        v = next(m for m in posed if m.name == part.name).vertices.astype(np.float64)
        out[inside[skin_out(body[inside], v, part.faces, reach=THROUGH_REACH)]] = True
    return out[faces].any(axis=1)


def turned(posed: list, R: np.ndarray) -> list:
    """The posed meshes and strands turned by the rigid transform `R` (4x4): the character seen from another side
    (posing with `R` applied after the root gives the same surfaces, but a simulated frame would be simulated again)."""
    from rh_dataset.characters.character import PosedStrands

    A, t = np.asarray(R, np.float64)[:3, :3], np.asarray(R, np.float64)[:3, 3]
    out = []
    for m in posed:
        if isinstance(m, PosedStrands):
            out.append(dataclasses.replace(m, points=(m.points.astype(np.float64) @ A.T + t).astype(np.float32)))
        else:
            out.append(dataclasses.replace(m, vertices=(m.vertices.astype(np.float64) @ A.T + t).astype(np.float32),
                                           normals=(m.normals.astype(np.float64) @ A.T).astype(np.float32)))
    return out


def coloured_split(posed: list, classes: list[tuple[np.ndarray, np.ndarray]]) -> list:
    """The posed meshes with the body's faces of each class ((F,) bool, disjoint) moved to a mesh of their own, albedo
    the class's colour."""
    out = []
    for m in posed:
        if m.name != "body":  # its faces are anny's, in anny's order (seam vertices split)
            out.append(m)
            continue
        rest = np.ones(len(m.faces), bool)
        for mask, _ in classes:
            rest &= ~mask
        out.append(dataclasses.replace(m, faces=m.faces[rest]))
        for k, (mask, colour) in enumerate(classes):
            if mask.any():  # Mitsuba refuses a mesh without faces
                albedo = np.broadcast_to(np.asarray(colour, np.float32), (1, 1, 3)).copy()
                out.append(dataclasses.replace(m, name=f"body_class_{k}", faces=m.faces[mask],
                                               material=dataclasses.replace(m.material, albedo=albedo)))
    return out


def tuck_stats(character, bones, root, tuck_depth: float, repeats: int = 2) -> tuple[int, float, float]:
    """The body vertices (anny's) the tuck moved in this frame, and the seconds `pose_character` takes with the tuck
    and without it (the least of `repeats` runs each, alternating)."""
    from rh_dataset.characters import pose_character

    part = character.part("body")
    times, meshes = {tuck_depth: [], 0.0: []}, {}
    for _ in range(repeats):
        for depth in (tuck_depth, 0.0):
            t = time.perf_counter()
            meshes[depth] = next(m for m in pose_character(character, bones, root, tuck_depth=depth)
                                 if m.name == "body")
            times[depth].append(time.perf_counter() - t)
    moved = np.any(meshes[tuck_depth].vertices != meshes[0.0].vertices, axis=1)
    return len(np.unique(part.body_vertex[moved])), min(times[tuck_depth]), min(times[0.0])


def seen_pixels(character, bones, root, posed: list, covered: dict[str, np.ndarray], body_faces: np.ndarray,
                size: int, views: int) -> tuple[list[tuple[int, int, int]], int, tuple]:
    """Per view (the posed character, `posed`, turned about the vertical by 360 / views degrees each) the pixels that
    saw skin come out through the cloth, those that saw other skin from under the cloth and those that saw the
    character at all; the body faces through; and the view with the most of the first kind: its index, both masks
    and its albedo image."""
    from rh_dataset.characters.preview import render_preview
    from rh_dataset.poses.pose import rotation_about_z

    counts, shown = [], None
    # Which skin came through depends on the pose, not on the turn (a rigid motion of body and cloth together).
    through = through_faces(character, bones, root, posed, covered)
    under = body_faces & ~through
    n_faces = int(through.sum())
    for k in range(views):
        view = turned(posed, rotation_about_z(360.0 * k / views))
        # The same samples twice, the two kinds of skin coloured (green, blue) and then black: a pixel's green and
        # blue differences are the shares of its samples that saw each, whatever the garments' own colours.
        a = render_preview(coloured_split(view, [(through, (0, 1, 0)), (under, (0, 0, 1))]), width=size,
                           height=size, spp=4, seed=k, albedo=True)
        b = render_preview(coloured_split(view, [(through, (0, 0, 0)), (under, (0, 0, 0))]), width=size,
                           height=size, spp=4, seed=k, albedo=True)
        seen_through, seen_under = (a[..., 1] - b[..., 1]) >= SHARE, (a[..., 2] - b[..., 2]) >= SHARE
        person = (a.max(axis=-1) > 0.0).sum()  # the albedo AOV is 0 where no surface was hit
        counts.append((int(seen_through.sum()), int(seen_under.sum()), int(person)))
        if shown is None or counts[-1][0] > counts[shown[0]][0]:
            shown = (k, seen_through, seen_under, a)
    return counts, n_faces, shown


def print_modes(posed: list[PosedFrame]) -> None:
    """The posed frames by the mode their cloth took: frames, the skin vertices out through the cloth after posing
    (`skin_out_count` over `SIMULATED_KINDS`, what "auto" weighs: all, the most in one frame; and over every draped
    part: all) and the posing's seconds (mean, most)."""
    print("\n| cloth posed | frames | skin vertices out (simulated kinds), all | most in one frame | "
          "through every draped part, all | posing s, mean | most |\n|---|---:|---:|---:|---:|---:|---:|")
    for mode in sorted({r.mode for r in posed}) + ["all"]:
        rows = [r for r in posed if mode in ("all", r.mode)]
        print(f"| {mode} | {len(rows)} | {sum(r.skin_out for r in rows)} | {max(r.skin_out for r in rows)} | "
              f"{sum(r.skin_out_all for r in rows)} | {sum(r.posing_s for r in rows) / len(rows):.2f} | "
              f"{max(r.posing_s for r in rows):.2f} |")
    print("most skin out: " + ", ".join(f"subject {r.subject} {r.label} {r.skin_out} ({r.mode})"
                                       for r in sorted(posed, key=lambda r: -r.skin_out)[:8]))
    from rh_dataset.characters.cloth_pose import SIMULATE_ABOVE, STRETCHED_ABOVE

    skinned = [r for r in posed if r.mode == "skinned"]
    if skinned:  # a simulated frame's count is the simulation's, not what decided it
        over = [r for r in skinned if r.skin_out > SIMULATE_ABOVE]
        print(f"skinned frames with more than cloth_pose.SIMULATE_ABOVE = {SIMULATE_ABOVE} skin vertices out (what "
              f"\"auto\" simulates): {len(over)} of {len(skinned)}" +
              "".join(f"; subject {r.subject} {r.label} {r.skin_out}" for r in over))
        taut = [r for r in skinned if r.stretched > STRETCHED_ABOVE]
        print(f"skinned frames whose skirt or dress has more than cloth_pose.STRETCHED_ABOVE = {STRETCHED_ABOVE:.0%} "
              f"of its edges stretched past 20 % (what \"auto\" also simulates): {len(taut)} of {len(skinned)}" +
              "".join(f"; subject {r.subject} {r.label} {100 * r.stretched:.1f} %" for r in taut))
    auto = [r for r in posed if r.mode == "simulated" and r.auto]  # the frames "auto" chose to simulate
    if auto:
        by_skin = sum(r.skin_out_skinned > SIMULATE_ABOVE for r in auto)
        by_stretch = sum(r.stretched_skinned > STRETCHED_ABOVE for r in auto)
        print(f"\"auto\" simulated {len(auto)} frames: {by_skin} for the skin out, {by_stretch} for the stretch "
              f"(both: {by_skin + by_stretch - len(auto)}); the skirts' and dresses' stretch, skinned -> simulated: " +
              ", ".join(f"subject {r.subject} {r.label} {100 * r.stretched_skinned:.1f} -> {100 * r.stretched:.1f} %"
                        for r in auto))


def print_by_label(posed: list[PosedFrame]) -> None:
    """The posed frames' counts summed by pose label: frames, frames with any pixel of skin through the cloth, those
    pixels, and the most in one view as a share of the character's pixels in that view; then the frames in order of
    their pixels through the cloth (the first 5)."""
    print("\n| pose label | frames | with skin through the cloth | its pixels, all views | most in one view "
          "(share of the character's pixels) | other skin from under the cloth, pixels |"
          "\n|---|---:|---:|---:|---|---:|")
    labels = sorted({r.label for r in posed})
    for label in labels + ["all"]:
        rows = [r.counts for r in posed if label in ("all", r.label)]
        views = [v for c in rows for v in c]
        most = max(views, key=lambda v: (v[0] / max(v[2], 1), v[0]))
        print(f"| {label} | {len(rows)} | {sum(1 for c in rows if any(v[0] for v in c))} | "
              f"{sum(v[0] for v in views)} | {most[0]} ({100.0 * most[0] / max(most[2], 1):.2f} %) | "
              f"{sum(v[1] for v in views)} |")
    order = sorted(posed, key=lambda r: -sum(v[0] for v in r.counts))[:5]
    print("most skin through the cloth: " + ", ".join(f"subject {r.subject} {r.label} "
                                                       f"{sum(v[0] for v in r.counts)}"
                                                       for r in order))


def print_stretch_by_kind(posed: list[PosedFrame], what_auto_adds: bool = True) -> None:
    """--stretch-by-kind: each draped kind's share of edges stretched past `cloth_pose.STRETCH_LIMIT` as posed, by
    pose label: frames that wear it, median, most, and frames over `cloth_pose.STRETCHED_ABOVE` (what "auto" would
    simulate if it weighed that kind); then each kind's five most stretched frames."""
    from rh_dataset.characters.cloth_pose import SIMULATE_ABOVE, SIMULATED_KINDS, STRETCH_KINDS, STRETCHED_ABOVE

    kinds = sorted({k for r in posed for k in r.by_kind})
    print(f"\n| draped kind (weighed by \"auto\": {', '.join(STRETCH_KINDS)}) | pose label | frames | median % | "
          f"most % | over {STRETCHED_ABOVE:.0%} |\n|---|---|---:|---:|---:|---:|")
    for kind in kinds:
        rows = [r for r in posed if kind in r.by_kind]
        for label in sorted({r.label for r in rows}) + ["all"]:
            v = np.array([r.by_kind[kind] for r in rows if label in ("all", r.label)])
            print(f"| {kind} | {label} | {len(v)} | {100 * np.median(v):.1f} | {100 * v.max():.1f} | "
                  f"{int(np.sum(v > STRETCHED_ABOVE))} |")
    # What weighing another kind's stretch would add: frames over the threshold in it that "auto" leaves skinned
    # today, each kind alone and all of them together; only kinds the simulation poses (the draped sleeves are always
    # skinned). The skinned shares decide, so not with --cloth simulated.
    if what_auto_adds:
        left = [r for r in posed if r.skin_out_skinned <= SIMULATE_ABOVE and r.stretched_skinned <= STRETCHED_ABOVE]
        others = [k for k in kinds if k not in STRETCH_KINDS and k in SIMULATED_KINDS]
        added = [f"{k} {sum(r.by_kind.get(k, 0.0) > STRETCHED_ABOVE for r in left)}" for k in others]
        n_all = sum(any(r.by_kind.get(k, 0.0) > STRETCHED_ABOVE for k in others) for r in left)
        print(f"\n\"auto\" simulates {len(posed) - len(left)} of these {len(posed)} posed frames; weighing another "
              f"simulated kind's stretch too would add: {', '.join(added)}; all of them {n_all}")
    for kind in kinds:
        top = sorted((r for r in posed if kind in r.by_kind), key=lambda r: -r.by_kind[kind])[:5]
        print(f"most stretched {kind}: " + ", ".join(f"subject {r.subject} {r.label} {100 * r.by_kind[kind]:.1f} % "
                                                    f"({r.mode})" for r in top))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--subjects", required=True, help="comma-separated benchmark subject indices of seed --seed")
    ap.add_argument("--poses", type=int, default=3, help="test poses per subject besides the rest pose (default 3)")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed whose subjects are used (default 0)")
    ap.add_argument("--size", type=int, default=512, help="square render size in pixels (default 512)")
    ap.add_argument("--views", type=int, default=4, help="directions around the subject (default 4)")
    ap.add_argument("--tuck-depth", type=float, default=None,
                    help="metres under the cloth that posing tucks skin come out through it (default "
                         "cloth_pose.TUCK_DEPTH; 0: not tucked)")
    ap.add_argument("--cloth", default="skinned", choices=("skinned", "simulated", "auto"),
                    help="how draped cloth is posed (`pose_character`'s cloth mode; default skinned, as the draft and "
                         "standard presets did before \"auto\"; simulated: tens of seconds a posed frame)")
    ap.add_argument("--no-render", action="store_true",
                    help="pose and count only (the mode taken, the skin out through the cloth, the posing's seconds): "
                         "no pixels")
    ap.add_argument("--figure", type=Path, default=None,
                    help="PNG of the posed frame and view with the most pixels of skin through the cloth")
    ap.add_argument("--stretch-figure", type=Path, default=None,
                    help="with --cloth auto: PNG of the (up to 3) frames simulated for their skirt's or dress's "
                         "stretch, the most stretched first: front and side, skinned | simulated (preview renders); "
                         "with --cloth simulated: the frames whose simulated kinds, any of them, are stretched over "
                         "the threshold skinned")
    ap.add_argument("--figure-above", type=float, default=None,
                    help="--stretch-figure with --cloth simulated: the skinned share over which a frame is drawn "
                         "(default cloth_pose.STRETCHED_ABOVE, 0.14)")
    ap.add_argument("--stretch-by-kind", action="store_true",
                    help="also each draped kind's share of edges stretched past 20 %% per frame, summed by kind and "
                         "pose label at the end (\"auto\" weighs only skirts and dresses)")
    args = ap.parse_args(argv)
    try:
        subjects = [int(s) for s in args.subjects.split(",") if s.strip()]
    except ValueError:
        raise SystemExit(f"--subjects: comma-separated integers, got {args.subjects!r}") from None
    if not subjects or args.poses < 0 or args.size < 16 or args.views < 1:
        raise SystemExit("--subjects: at least one; --poses >= 0, --size >= 16 and --views >= 1")
    if args.stretch_figure is not None and args.cloth == "skinned":
        raise SystemExit("--stretch-figure: needs --cloth auto or simulated (frames simulated for the stretch)")
    if args.tuck_depth is not None and not (np.isfinite(args.tuck_depth) and args.tuck_depth >= 0):
        raise SystemExit(f"--tuck-depth: metres >= 0, got {args.tuck_depth}")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_cloth_pose import load, test_source

    from rh_dataset.characters import cloth_stretch, pose_character, skin_out_count
    from rh_dataset.characters.cloth_pose import SIMULATED_KINDS, STRETCH_KINDS, STRETCHED_ABOVE, TUCK_DEPTH
    from rh_dataset.characters.drape import DRAPED_KINDS

    tuck = TUCK_DEPTH if args.tuck_depth is None else args.tuck_depth
    if args.figure_above is None:
        args.figure_above = STRETCHED_ABOVE
    elif not 0.0 <= args.figure_above < 1.0:
        raise SystemExit(f"--figure-above: a share in [0, 1), got {args.figure_above}")
    source, split = test_source(args.seed)
    print(f"{args.size}x{args.size}, {args.views} views, a pixel counted where >= {SHARE:.0%} of its samples saw the "
          f"skin; draped cloth {args.cloth}; skin through the cloth tucked {1e3 * tuck:g} mm under it; load {load()}")
    print("| subject | pose | cloth posed | skin vertices out: simulated kinds (`skin_out_count`, its time) / every "
          "draped part | skirt's or dress's edges stretched past 20 %, % (skinned) | posing s | "
          "skin faces through | pixels, skin through the cloth, per view | all | pixels, other skin from under the "
          "cloth, per view | all | character's pixels, all views | body vertices tucked | posing s, tucked / not |"
          "\n|---|---|---|---:|---:|---:|---:|---|---:|---|---:|---:|---:|---|")
    worst, posed, taut = None, [], []
    for s in subjects:
        subject = source.subject(s)
        ch = subject.character
        covered = covered_skin(ch)
        body_faces = under_faces(covered)
        frames = [("rest", None, None)] + [(p.label, dict(p.bones), p.root_transform)
                                           for p in (source.pose(subject, split, j) for j in range(args.poses))]
        for j, (label, bones, root) in enumerate(frames):
            t = time.perf_counter()
            stats = {}
            meshes = pose_character(ch, bones, root, args.cloth, cloth_stats=stats if args.cloth == "auto" else None,
                                    tuck_depth=tuck)
            t_pose = time.perf_counter() - t
            stretched = cloth_stretch(ch, meshes, STRETCH_KINDS)  # after the timing: the bench's, not the posing's
            decided = stats.get("stretched", stretched)  # "auto": the skinned share it chose by
            mode = stats.get("mode", args.cloth)
            t_count = time.perf_counter()
            n_out = skin_out_count(ch, meshes, SIMULATED_KINDS)  # what "auto" adds to a frame it leaves skinned
            t_count = time.perf_counter() - t_count
            n_all = skin_out_count(ch, meshes)
            row = (f"| {s} | {j - 1 if j else '-'} {label} | {mode} | {n_out} ({1e3 * t_count:.0f} ms) / {n_all} | "
                   f"{100 * stretched:.1f} ({100 * decided:.1f}) | {t_pose:.2f} |")
            if args.no_render:
                counts, n_faces, first = [], 0, None
                row += " - | - | - | - | - | - | - | - |"
            else:
                counts, n_faces, first = seen_pixels(ch, bones, root, meshes, covered, body_faces, args.size,
                                                     args.views)
                n_t, n_u = sum(c[0] for c in counts), sum(c[1] for c in counts)
                row += (f" {n_faces} | {' / '.join(str(c[0]) for c in counts)} | {n_t} | "
                        f"{' / '.join(str(c[1]) for c in counts)} | {n_u} | {sum(c[2] for c in counts)} |")
                if args.cloth == "skinned":  # the tuck's cost: posed again, with and without it
                    n_tucked, t_tuck, t_plain = tuck_stats(ch, bones, root, tuck)
                    row += f" {n_tucked} | {t_tuck:.3f} / {t_plain:.3f} |"
                else:
                    row += " - | - |"
                if bones is not None and (worst is None or n_t > worst[0]):
                    worst = (n_t, s, label, first)
            if bones is not None and stats.get("mode") == "simulated" and decided > STRETCHED_ABOVE:
                taut.append((decided, s, label, ch, bones, root, meshes))
            elif bones is not None and args.stretch_figure is not None and args.cloth == "simulated":
                # every kind the simulation poses, weighed as posed skinned (what "auto" would weigh)
                share = cloth_stretch(ch, pose_character(ch, bones, root, "skinned"), SIMULATED_KINDS)
                if share > args.figure_above:
                    taut.append((share, s, label, ch, bones, root, meshes))
            by_kind = ({p.name: cloth_stretch(ch, meshes, (p.name,)) for p in ch.parts
                        if p.name in DRAPED_KINDS and p.skinning is not None} if args.stretch_by_kind else {})
            if bones is not None:
                posed.append(PosedFrame(s, label, counts, mode, n_out, t_pose, n_all, stretched,
                                        stats.get("skin_out", n_out), decided, bool(stats), by_kind))
            print(f"{row}  ({time.perf_counter() - t:.1f} s)", flush=True)
    print(f"\nload {load()}")
    if posed:
        print_modes(posed)
    if posed and not args.no_render:
        print(f"posed frames: {sum(v[0] for r in posed for v in r.counts)} pixels of skin through the cloth, "
              f"{sum(v[1] for r in posed for v in r.counts)} of other skin from under it (through openings or folds)")
        print_by_label(posed)
    if posed and args.stretch_by_kind:
        print_stretch_by_kind(posed, what_auto_adds=args.cloth != "simulated")
    if args.figure is not None and worst is not None:
        from rh_common.colourspace import quantize8, srgb_encode
        from rh_common.imageio import write_png

        n, s, label, (view, seen_through, seen_under, albedo) = worst
        img = quantize8(srgb_encode(np.clip(albedo, 0.0, 1.0)))
        for mask, colour in ((seen_under, (0, 255, 255)), (seen_through, (255, 0, 255))):
            ring = mask.copy()
            for dy in range(-3, 4):
                for dx in range(-3, 4):
                    ring |= np.roll(np.roll(mask, dy, 0), dx, 1)
            img[ring & ~mask] = colour
        write_png(args.figure, img)
        print(f"wrote {args.figure}: subject {s}, {label}, view {view} ({360 * view // args.views} degrees); skin "
              f"through the cloth (green) ringed in magenta, other skin from under it (blue) in cyan")
    if args.stretch_figure is not None:
        stretch_figure(args.stretch_figure, sorted(taut, key=lambda t: -t[0])[:3])
    return 0


def stretch_figure(path: Path, frames: list[tuple]) -> None:
    """Rows: the frames "auto" simulated for the stretch, or (--cloth simulated) those any simulated kind of which is
    stretched over the threshold skinned ((skinned share, subject, label, character, bones, root, simulated meshes));
    columns: front skinned | front simulated | side skinned | side simulated, preview renders
    (`preview.render_preview`, 64 spp, the same seed) in display sRGB."""
    from rh_common.colourspace import quantize8, to_display
    from rh_common.imageio import write_png
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.preview import render_preview
    from rh_dataset.poses.pose import rotation_about_z

    if not frames:
        print(f"--stretch-figure: no frame was simulated for its stretch; {path} not written")
        return
    rows = []
    for share, s, label, ch, bones, root, simulated in frames:
        skinned = pose_character(ch, bones, root, "skinned")
        tiles = [render_preview(turned(m, rotation_about_z(a)), 256, 384, 64) for a in (0.0, 90.0)
                 for m in (skinned, simulated)]
        rows.append(np.concatenate([quantize8(to_display(t, 1.0)) for t in tiles], axis=1))
        print(f"--stretch-figure row {len(rows)}: subject {s} {label}, {100 * share:.1f} % of the edges past 20 % "
              "skinned")
    write_png(path, np.concatenate(rows, axis=0))
    print(f"wrote {path}: rows as listed; front skinned | front simulated | side skinned | side simulated")


if __name__ == "__main__":
    raise SystemExit(main())
