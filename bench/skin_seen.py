"""Skin a camera sees through draped cloth, counted in pixels: the image-space check of issue 17's "no cloth passes
through the body visibly".

    python bench/skin_seen.py --subjects 14,18 --poses 3 [--size 512] [--views 4] [--tuck-depth M]
                               [--figure out.png]

In: seed `--seed`'s benchmark subjects (protocol a's test split, built as at the `standard` preset: full drapes) and
their first `--poses` test poses, skinned as `rh-generate` poses them. The body's faces that lie inside a draped
garment at rest (`cloth_pose.skin_inside` of every draped part, or the part's own `inside_skin`) are coloured: green
where a corner came out through the posed cloth (`cloth_pose.layer_depth` < 0 within
`bench_cloth_pose.THROUGH_REACH`, the `through` of bench_cloth_pose.py), blue where all lie under it still. The
posed character's albedo AOV is rendered (`preview.render_preview`, 4 spp) from `--views` directions around it (the
character turned about the vertical), twice with the same samples: those colours, then black. Out, per frame: the
body faces through, per view and in all the pixels where at least a quarter of the samples saw each kind (the
green, resp. blue, difference of the two renders), whatever the garments' own colours, the pixels that saw the
character at all, then the body vertices the tuck moved and `pose_character`'s seconds with and without it
(`tuck_stats`); the rest pose first as the check (none through, none tucked expected). At the end, the posed frames
summed by pose label (`print_by_label`). Which faces are coloured is decided on anny's posed body; the render shows
the body as posing leaves it, its skin out through the cloth tucked `--tuck-depth` under it (`cloth_pose.tuck_skin`;
0: as the cloth leaves it), so green pixels are skin the tuck left out, or skin seen through a gap. Blue pixels
are skin seen from under the cloth: through a hem, a cuff or a neckline (legitimately), or through gaps where the
skinned cloth folds through itself. Skin under shell garments is culled
by the renderer and not counted. `bench_cloth_pose.py`'s `seen_around` says which vertices could be seen (a ray to
8 cameras); this says how many pixels are. `--figure`: the posed frame and view with the most green pixels, those
ringed in magenta and the blue ones in cyan.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

SHARE = 0.25  # a pixel counts when at least this share of its samples saw the skin


def covered_skin(character, rest_meshes) -> dict[str, np.ndarray]:
    """{draped part: anny body vertex indices inside it at rest}: the part's own `inside_skin` where posing keeps one
    (`cloth_pose.LIFT_KINDS`), else `cloth_pose.skin_inside` of the cloth as posing leaves it at rest."""
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.cloth_pose import skin_inside
    from rh_dataset.characters.drape import DRAPED_KINDS
    from rh_dataset.mesh import vertex_normals

    rest = run_anny(character.phenotype, None)["vertices"]
    normals = vertex_normals(rest, body_topology().faces)
    out = {}
    for part in character.parts:
        if part.name not in DRAPED_KINDS:
            continue
        if part.inside_skin is not None:
            out[part.name] = np.asarray(part.inside_skin, np.int64)
            continue
        v = next(m for m in rest_meshes if m.name == part.name).vertices.astype(np.float64)
        out[part.name] = skin_inside(v, part.faces, rest, normals)
    return out


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
    draped part at rest and outside its posed surface now (`cloth_pose.layer_depth` < 0 within bench_cloth_pose's
    THROUGH_REACH): skin come out through it."""
    from bench_cloth_pose import THROUGH_REACH

    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.cloth_pose import layer_depth

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
        d = layer_depth(body[inside], v, part.faces, near=THROUGH_REACH)
        out[inside[np.isfinite(d) & (d < 0)]] = True
    return out[faces].any(axis=1)


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


def seen_pixels(character, bones, root, covered: dict[str, np.ndarray], body_faces: np.ndarray, size: int,
                views: int, tuck_depth: float) -> tuple[list[tuple[int, int, int]], int, tuple]:
    """Per view (the character turned about the vertical by 360 / views degrees each) the pixels that saw skin come
    out through the cloth, those that saw other skin from under the cloth and those that saw the character at all;
    the body faces through; and the view with the most of the first kind: its index, both masks and its albedo
    image."""
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.preview import render_preview
    from rh_dataset.poses.pose import rotation_about_z

    counts, shown = [], None
    # Which skin came through depends on the pose, not on the turn (a rigid motion of body and cloth together):
    # found once, in the unturned frame.
    through = through_faces(character, bones, root, pose_character(character, bones, root), covered)
    under = body_faces & ~through
    n_faces = int(through.sum())
    for k in range(views):
        R = rotation_about_z(360.0 * k / views)
        posed = pose_character(character, bones, R if root is None else R @ root, tuck_depth=tuck_depth)
        # The same samples twice, the two kinds of skin coloured (green, blue) and then black: a pixel's green and
        # blue differences are the shares of its samples that saw each, whatever the garments' own colours.
        a = render_preview(coloured_split(posed, [(through, (0, 1, 0)), (under, (0, 0, 1))]), width=size,
                           height=size, spp=4, seed=k, albedo=True)
        b = render_preview(coloured_split(posed, [(through, (0, 0, 0)), (under, (0, 0, 0))]), width=size,
                           height=size, spp=4, seed=k, albedo=True)
        seen_through, seen_under = (a[..., 1] - b[..., 1]) >= SHARE, (a[..., 2] - b[..., 2]) >= SHARE
        person = (a.max(axis=-1) > 0.0).sum()  # the albedo AOV is 0 where no surface was hit
        counts.append((int(seen_through.sum()), int(seen_under.sum()), int(person)))
        if shown is None or counts[-1][0] > counts[shown[0]][0]:
            shown = (k, seen_through, seen_under, a)
    return counts, n_faces, shown


def print_by_label(posed: list[tuple[int, str, list[tuple[int, int, int]]]]) -> None:
    """The posed frames' counts summed by pose label: frames, frames with any pixel of skin through the cloth, those
    pixels, and the most in one view as a share of the character's pixels in that view; then the frames in order of
    their pixels through the cloth (the first 5)."""
    print("\n| pose label | frames | with skin through the cloth | its pixels, all views | most in one view "
          "(share of the character's pixels) | other skin from under the cloth, pixels |"
          "\n|---|---:|---:|---:|---|---:|")
    labels = sorted({label for _, label, _ in posed})
    for label in labels + ["all"]:
        rows = [c for _, lab, c in posed if label in ("all", lab)]
        views = [v for c in rows for v in c]
        most = max(views, key=lambda v: (v[0] / max(v[2], 1), v[0]))
        print(f"| {label} | {len(rows)} | {sum(1 for c in rows if any(v[0] for v in c))} | "
              f"{sum(v[0] for v in views)} | {most[0]} ({100.0 * most[0] / max(most[2], 1):.2f} %) | "
              f"{sum(v[1] for v in views)} |")
    order = sorted(posed, key=lambda r: -sum(v[0] for v in r[2]))[:5]
    print("most skin through the cloth: " + ", ".join(f"subject {s} {label} {sum(v[0] for v in c)}"
                                                       for s, label, c in order))


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
    ap.add_argument("--figure", type=Path, default=None,
                    help="PNG of the posed frame and view with the most pixels of skin through the cloth")
    args = ap.parse_args(argv)
    try:
        subjects = [int(s) for s in args.subjects.split(",") if s.strip()]
    except ValueError:
        raise SystemExit(f"--subjects: comma-separated integers, got {args.subjects!r}") from None
    if not subjects or args.poses < 0 or args.size < 16 or args.views < 1:
        raise SystemExit("--subjects: at least one; --poses >= 0, --size >= 16 and --views >= 1")
    if args.tuck_depth is not None and not (np.isfinite(args.tuck_depth) and args.tuck_depth >= 0):
        raise SystemExit(f"--tuck-depth: metres >= 0, got {args.tuck_depth}")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_cloth_pose import load, test_source

    from rh_dataset.characters import pose_character
    from rh_dataset.characters.cloth_pose import TUCK_DEPTH

    tuck = TUCK_DEPTH if args.tuck_depth is None else args.tuck_depth
    source, split = test_source(args.seed)
    print(f"{args.size}x{args.size}, {args.views} views, a pixel counted where >= {SHARE:.0%} of its samples saw the "
          f"skin; skin through the cloth tucked {1e3 * tuck:g} mm under it; load {load()}")
    print("| subject | pose | skin faces through | pixels, skin through the cloth, per view | all | pixels, other "
          "skin from under the cloth, per view | all | character's pixels, all views | body vertices tucked | "
          "posing s, tucked / not |\n|---|---|---:|---|---:|---|---:|---:|---:|---|")
    worst, posed = None, []
    for s in subjects:
        subject = source.subject(s)
        ch = subject.character
        covered = covered_skin(ch, pose_character(ch, None, None))
        body_faces = under_faces(covered)
        frames = [("rest", None, None)] + [(p.label, dict(p.bones), p.root_transform)
                                           for p in (source.pose(subject, split, j) for j in range(args.poses))]
        for j, (label, bones, root) in enumerate(frames):
            t = time.perf_counter()
            counts, n_faces, first = seen_pixels(ch, bones, root, covered, body_faces, args.size, args.views, tuck)
            n_t, n_u = sum(c[0] for c in counts), sum(c[1] for c in counts)
            if bones is not None:
                posed.append((s, label, counts))
            seconds = time.perf_counter() - t
            n_tucked, t_tuck, t_plain = tuck_stats(ch, bones, root, tuck)
            print(f"| {s} | {j - 1 if j else '-'} {label} | {n_faces} | {' / '.join(str(c[0]) for c in counts)} | "
                  f"{n_t} | {' / '.join(str(c[1]) for c in counts)} | {n_u} | {sum(c[2] for c in counts)} | "
                  f"{n_tucked} | {t_tuck:.3f} / "
                  f"{t_plain:.3f} |  ({seconds:.1f} s)", flush=True)
            if bones is not None and (worst is None or n_t > worst[0]):
                worst = (n_t, s, label, first)
    print(f"\nposed frames: {sum(v[0] for _, _, c in posed for v in c)} pixels of skin through the cloth, "
          f"{sum(v[1] for _, _, c in posed for v in c)} of other skin from under it (through openings or folds); "
          f"load {load()}")
    if posed:
        print_by_label(posed)
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
