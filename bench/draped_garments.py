"""Benchmark subjects in loose garments: the first draped-dress, draped-skirt, draped-trousers, draped-coat,
draped-hoodie, draped-jacket, draped-tshirt, draped-longsleeve, draped-shorts and draped-straight-trousers wearers
among a dataset seed's
subjects (or the subjects named), draped at a drape level, rendered rest front | rest side | a posed frame front |
side (`--turns`: other views, e.g. from the back), with the drape's seconds and how deep any cloth vertex sits in the
body in each view.

    python bench/draped_garments.py --out docs/draped_garments.png           # 2 dresses + 2 skirts, full drape
    python bench/draped_garments.py --dresses 1 --skirts 1 --drape coarse    # quicker look
    python bench/draped_garments.py --dresses 0 --skirts 0 --trousers 3 --tile 512 --out docs/draped_trousers.png
    python bench/draped_garments.py ... --trousers 3 --swap-trousers   # shell-trousers wearers put in draped ones
    python bench/draped_garments.py --dresses 0 --skirts 0 --coats 2 --tile 512 --out docs/draped_coat.png
    python bench/draped_garments.py --dresses 0 --skirts 0 --hoodies 1 --turns 180,135 --tile 512 \
        --out docs/draped_hoodie.png                                      # the hood, from the back and back-left
    python bench/draped_garments.py --subjects 7,48 --tile 512 --out docs/draped_jacket.png  # two open jackets
    python bench/draped_garments.py --subjects 3,31 --tile 512 --out docs/draped_tshirt.png  # two loose t-shirts
    python bench/draped_garments.py --subjects 11,36 --tile 512 --out docs/draped_longsleeve.png  # loose long sleeves
    python bench/draped_garments.py --subjects 1,8,23,44 --tile 512 --out docs/draped_shorts.png  # loose shorts
    python bench/draped_garments.py --subjects 23,30 --tile 512 --crop 0.3,0.38,0.7,0.72 --zoom 2 \
        --out docs/trousers_print.png  # the hips at 2x: a check running across the split ring
    python bench/draped_garments.py --subjects 9,18,42,47 --tile 512 \
        --out docs/draped_straight_trousers.png                           # straight-leg trousers
    python bench/draped_garments.py --dresses 0 --skirts 0 --straight 2   # the first two straight-trousers wearers

In: the dataset seed (the generator's subject order: `sample_recipe(rng_for(seed, "character", s))`), how many
subjects of each kind (or `--subjects`: these indices, whatever they wear), the drape level (`drape.DRAPE_LEVELS`).
Out: a PNG sheet (a row per subject, 256 px tiles, Open Image Denoise on 32 spp: a look, not a dataset frame)
and, printed, per subject: its index, garments, drape wall seconds (0 when the drape cache already held it), the
cloth's depth under the skin (mm, > 0 inside: worst vertex and 99th percentile) at rest and posed, the cloth's
self-crossing edges (`cloth_pose.self_crossings`) at rest and posed, and the load average. The posed frame is
skinned (the draft and standard presets' cloth mode). `--swap-trousers`: subjects whose recipe draws the shell
`trousers` count as trousers wearers, in `draped_trousers` of the same colours (their recipes otherwise unmodified),
for a seed whose recipes do not draw the draped kind.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def loose_subjects(seed: int, dresses: int, skirts: int, limit: int = 200, trousers: int = 0,
                   swap_trousers: bool = False, coats: int = 0, hoodies: int = 0, jackets: int = 0,
                   tshirts: int = 0, longsleeves: int = 0, shorts: int = 0, straight: int = 0,
                   subjects: tuple[int, ...] = ()) -> list[tuple[int, object]]:
    """(subject index, recipe) of the first `dresses` draped-dress, `skirts` draped-skirt, `trousers`
    draped-trousers, `coats` draped-coat, `hoodies` draped-hoodie, `jackets` draped-jacket, `tshirts`
    draped-tshirt, `longsleeves` draped-longsleeve, `shorts` draped-shorts and `straight` draped-straight-trousers
    wearers of `seed` (`swap_trousers`:
    shell-trousers wearers put in draped ones), or of the `subjects` given by index."""
    import dataclasses

    from rh_dataset.characters import sample_recipe
    from rh_dataset.generate.seeding import rng_for

    want = {"draped_dress": dresses, "draped_skirt": skirts, "draped_trousers": trousers, "draped_coat": coats,
            "draped_hoodie": hoodies, "draped_jacket": jackets, "draped_tshirt": tshirts,
            "draped_longsleeve": longsleeves, "draped_shorts": shorts, "draped_straight_trousers": straight}
    if subjects:
        return [(s, sample_recipe(rng_for(seed, "character", s), pool="benchmark", index=s)) for s in subjects]
    out = []
    for s in range(limit):
        r = sample_recipe(rng_for(seed, "character", s), pool="benchmark", index=s)
        if swap_trousers and r.garment("trousers") is not None:
            r = dataclasses.replace(r, garments=tuple(dataclasses.replace(g, kind="draped_trousers")
                                                      if g.kind == "trousers" else g for g in r.garments))
        kind = next((g.kind for g in r.garments if g.kind in want and want[g.kind] > 0), None)
        if kind is not None and want[kind] > 0:
            want[kind] -= 1
            out.append((s, r))
        if not any(want.values()):
            break
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0, help="dataset seed whose subjects are searched")
    ap.add_argument("--dresses", type=int, default=2, help="draped-dress wearers")
    ap.add_argument("--skirts", type=int, default=2, help="draped-skirt wearers")
    ap.add_argument("--trousers", type=int, default=0, help="wide-trousers (draped_trousers) wearers")
    ap.add_argument("--coats", type=int, default=0, help="open-coat (draped_coat) wearers")
    ap.add_argument("--hoodies", type=int, default=0, help="hoodie (draped_hoodie) wearers")
    ap.add_argument("--jackets", type=int, default=0, help="open-jacket (draped_jacket) wearers")
    ap.add_argument("--tshirts", type=int, default=0, help="loose t-shirt (draped_tshirt) wearers")
    ap.add_argument("--longsleeves", type=int, default=0, help="loose long sleeve (draped_longsleeve) wearers")
    ap.add_argument("--shorts", type=int, default=0, help="loose shorts (draped_shorts) wearers")
    ap.add_argument("--straight", type=int, default=0,
                    help="straight-leg trousers (draped_straight_trousers) wearers")
    ap.add_argument("--subjects", default="", help="comma-separated subject indices to show instead of a search")
    ap.add_argument("--turns", default="0,90",
                    help="the two views, degrees about +Z (0: from the front, 90: its left, 180: from the back)")
    ap.add_argument("--swap-trousers", action="store_true",
                    help="shell-trousers wearers count as draped-trousers wearers (in draped_trousers)")
    ap.add_argument("--drape", default="full", help="drape level (full: the benchmark's; coarse: draft's)")
    ap.add_argument("--tile", type=int, default=256, help="tile size in pixels")
    ap.add_argument("--crop", default="",
                    help="x0,y0,x1,y1: keep this part of every tile, as fractions of it (0,0 its top left; "
                         "default the whole tile)")
    ap.add_argument("--zoom", type=int, default=1, help="magnify every (cropped) tile this many times, nearest")
    ap.add_argument("--out", type=Path, default=Path("/tmp/draped_garments.png"),
                    help="PNG sheet written (default /tmp/draped_garments.png)")
    args = ap.parse_args(argv)
    crop = tuple(float(x) for x in args.crop.split(",")) if args.crop else (0.0, 0.0, 1.0, 1.0)
    if len(crop) != 4 or not (0 <= crop[0] < crop[2] <= 1 and 0 <= crop[1] < crop[3] <= 1) or args.zoom < 1:
        raise SystemExit(f"--crop: x0,y0,x1,y1 with 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1, got {args.crop!r}; "
                         f"--zoom: 1 or more, got {args.zoom}")
    rows_px = slice(int(round(crop[1] * args.tile)), int(round(crop[3] * args.tile)))
    cols_px = slice(int(round(crop[0] * args.tile)), int(round(crop[2] * args.tile)))

    from rh_common.body_model import load_anny
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.cloth_pose import self_crossings
    from rh_dataset.characters.drape import DRAPED_KINDS, penetration
    from rh_dataset.characters.sleeves import SLEEVE_CUTS
    from rh_dataset.characters.preview import render_preview
    from rh_dataset.poses import sample_poses
    from rh_dataset.poses.pose import rotation_about_z

    load = lambda: " ".join(open("/proc/loadavg").read().split()[:3])  # noqa: E731
    turns = tuple(float(t) for t in args.turns.split(","))
    if len(turns) != 2:
        raise SystemExit(f"--turns: two angles in degrees, comma-separated, got {args.turns!r}")
    faces = body_topology().faces
    pose = next(p for p in sample_poses(np.random.default_rng(7), load_anny(), 8) if p.label == "walk")
    rows = []
    for s, recipe in loose_subjects(args.seed, args.dresses, args.skirts, trousers=args.trousers,
                                    swap_trousers=args.swap_trousers, coats=args.coats, hoodies=args.hoodies,
                                    jackets=args.jackets, tshirts=args.tshirts,
                                    longsleeves=args.longsleeves, shorts=args.shorts, straight=args.straight,
                                    subjects=tuple(int(x) for x in args.subjects.split(",") if x)):
        t = time.perf_counter()
        character = build_character(recipe, 512, drape=args.drape)
        t_build = time.perf_counter() - t
        # The outermost draped part but the sleeves (bench_sleeves.py measures those): the coat's panels, the hood.
        kind = next(p.name for p in character.parts[::-1] if p.name in DRAPED_KINDS and p.name not in SLEEVE_CUTS)
        tiles, depth, crossings = [], [], []
        for bones, root in (({}, None), (dict(pose.bones), pose.root_transform)):
            run = run_anny(recipe.phenotype, bones)
            for i, turn in enumerate(turns):  # by default the front, then seen from its left
                R = rotation_about_z(turn)
                world = R if root is None else R @ root
                posed = pose_character(character, bones, world)
                if i == 0:  # the depth in the body turned as the cloth is
                    body = run["vertices"] @ world[:3, :3].T + world[:3, 3]
                    cloth = next(m for m in posed if m.name == kind)
                    d = penetration(body, faces, cloth.vertices)
                    depth.append((1e3 * float(d.max()), 1e3 * float(np.percentile(d, 99))))
                    crossings.append(self_crossings(cloth.vertices, cloth.faces))
                img = render_preview(posed, width=args.tile, height=args.tile, spp=32, seed=s, denoise=True)
                tile = quantize8(srgb_encode(np.clip(img, 0, None) * 1.3))[rows_px, cols_px]
                tiles.append(np.repeat(np.repeat(tile, args.zoom, axis=0), args.zoom, axis=1))
        rows.append(np.concatenate(tiles, axis=1))
        print(f"subject {s:3d} {','.join(g.kind for g in recipe.garments):40s} build (drape {args.drape}) "
              f"{t_build:6.1f} s  cloth depth in the body (worst / 99th percentile): rest {depth[0][0]:6.2f} / "
              f"{depth[0][1]:6.2f} mm, {pose.label} {depth[1][0]:6.2f} / {depth[1][1]:6.2f} mm  "
              f"self-crossing edges: rest {crossings[0]}, {pose.label} {crossings[1]}  (load {load()})", flush=True)
    write_png(args.out, np.concatenate(rows, axis=0))
    print(f"wrote {args.out}: rows = subjects, columns = rest at {turns[0]:g} | {turns[1]:g} degrees, {pose.label} at "
          f"{turns[0]:g} | {turns[1]:g} degrees (0: the front, 90: its left)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
