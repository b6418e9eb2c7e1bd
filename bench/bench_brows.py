"""Eyebrows and eyelashes: grown as strands or painted, what the protocol's pixels show of each, and their cost.

    python bench/bench_brows.py                          # subjects 22, 0, 7 (light, medium, dark skin)
    python bench/bench_brows.py --subjects 22 --figure docs/brows.png

The generator grows each brow as strands (`face_hair.build_brows`, character.FACE_HAIR: hairs rooted in the band
`textures.brow_band` places above each eye, of the scalp hair's fibres). Before, it painted that band into the
skin's albedo in a darkened hair colour (`skin_texture(..., brows=True)`, kept for this comparison). Lashes
(`face_hair.build_lashes`, along the upper lids) are not grown by the generator; here they are, over the brows.
For each subject, in the rest pose under Blender's studio HDRI, front view, rh-generate's --preset (standard; test
split), at two framings (--framings):

  protocol   the benchmark's camera (512 x 512, fov 30 degrees, `framing_box` + `frame_body`): its footprint at
             the brows printed in mm per pixel
  close-up   the head alone filling --closeup-fill of the 512 px frame (~0.5-0.7 mm a pixel)

it renders the painted subject with sample seeds 1 and 2, and the generated one (strand brows) and that one with
lashes with seed 1. Over the brows' pixels (the brow hairs' projected box, 2 px wider) it prints the PSNR (sRGB,
exposure x1.3) of strand brows against painted ones, and over the lashes' box that of lashes against none; beside
each, the PSNR of the two painted seeds (the Monte Carlo noise a change has to stand out of; the changes are
rendered with the same seed, so the noise mostly cancels in them) and the albedo layer's mean absolute difference,
likewise. Then the seconds of each frame (image and AOV passes): every variant rendered once untimed (that
compiles its scene's kernels), then --repeats timed rounds, the variants interleaved; the median, with the load
average. Per subject it also prints the seconds growing its brows takes (`build_brows`, once per subject build).
`--figure`: each subject's face at 4x (protocol) and 1x (close-up): painted | strand brows | with lashes, image
above albedo. `--clearance`: instead, for every subject wearing headwear, how close its brows come to each piece,
in the bind pose (caps, hats and glasses move rigidly with the head, as the brows do; only a scarf's hem bends
with the neck).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the bench folder's modules


def bind_error(geometry, feats) -> float:
    """The worst distance (m) between a bound control point's rest-pose anchor and the point grown there."""
    from rh_dataset.characters.body import anchor_points

    back = anchor_points(feats.rest_vertices, feats.rest_normals, geometry.blend_vertices, geometry.blend_weights,
                         geometry.offset)
    return float(np.linalg.norm(back - geometry.rest.reshape(-1, 3), axis=1).max())


def headwear_clearance(recipes) -> None:
    """For each subject wearing headwear: the closest any of its brow hairs' control points (bind pose, the
    generator's stream) comes to each piece's surface (bind pose; trimesh closest points)."""
    import trimesh

    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.character import _STREAM_FACE_HAIR
    from rh_dataset.characters.face_hair import build_brows
    from rh_dataset.characters.headwear import build_headwear

    worst = {}
    for s, r in enumerate(recipes):
        if not r.headwear:
            continue
        feats = body_features(r.phenotype)
        pieces = build_headwear(r.headwear, feats, r.phenotype, np.zeros(len(feats.rest_vertices)))
        brows = build_brows(feats, np.random.default_rng([r.seed, _STREAM_FACE_HAIR])).rest.reshape(-1, 3)
        row = []
        for h, g in zip(r.headwear, pieces):
            d = float(trimesh.proximity.closest_point(trimesh.Trimesh(g.vertices, g.faces, process=False),
                                                      brows)[1].min())
            worst[h.kind] = min(worst.get(h.kind, np.inf), d)
            row.append(f"{h.kind} {1e3 * d:.1f} mm")
        print(f"  subject {s:2d}: " + "; ".join(row), flush=True)
    print("  closest per kind: " + ", ".join(f"{k} {1e3 * v:.1f} mm" for k, v in sorted(worst.items())))


def _psnr(x, y, where) -> float:
    from rh_common.colourspace import srgb_encode

    a = srgb_encode(np.clip(x[where] * 1.3, 0, 1))
    b = srgb_encode(np.clip(y[where] * 1.3, 0, 1))
    return float(10 * np.log10(1.0 / max(float(np.mean((a - b) ** 2)), 1e-12)))


def _box(cam, points, shape, pad: int):
    uv = cam.project(np.asarray(points, np.float64).reshape(-1, 3))
    x0, y0 = np.floor(uv.min(0)).astype(int) - pad
    x1, y1 = np.ceil(uv.max(0)).astype(int) + pad
    m = np.zeros(shape[:2], bool)
    m[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)] = True
    return m, (max(x0, 0), max(y0, 0), x1, y1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", default="22,0,7", help="comma-separated benchmark subjects (rh-generate's)")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the recipes come from")
    ap.add_argument("--preset", default="standard", help="rh-generate's render preset (scenes/presets.json)")
    ap.add_argument("--spp", type=int, default=None, help="samples per pixel (default: the preset's)")
    ap.add_argument("--closeup-fill", type=float, default=0.9,
                    help="fraction of the frame the head fills in the close-up")
    ap.add_argument("--framings", nargs="+", default=["protocol", "close-up"], choices=("protocol", "close-up"),
                    help="the camera framings to render")
    ap.add_argument("--repeats", type=int, default=1, help="timed rounds of every variant (the median is printed)")
    ap.add_argument("--figure", type=Path, help="write the brow crops at 4x here (PNG)")
    ap.add_argument("--clearance", action="store_true",
                    help="only print how close the brows come to each headwear wearer's headwear (all subjects)")
    args = ap.parse_args(argv)
    if args.clearance:
        from subject_diversity import benchmark_recipes

        print(f"brows to headwear, protocol a, seed {args.seed} (bind pose; the headwear's surface):")
        headwear_clearance(benchmark_recipes("protocol_a", args.seed))
        return 0

    from subject_diversity import benchmark_recipes
    from subjects_gallery import studio_environment

    from rh_common.camera import frame_body
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import body_bounds, build_character, pose_character
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.hair_fibre import fibres_for_colour
    from rh_dataset.characters.character import (_STREAM_FACE_HAIR, _STREAM_SKIN, _STREAM_SKIN_DETAIL,
                                                  _split_fibres)
    from rh_dataset.characters.face_hair import BROW_HAIRS, POINTS, build_brows, build_lashes
    from rh_dataset.characters.textures import skin_texture
    from rh_dataset.cli import render_settings
    from rh_dataset.generate.subjects import CAMERA_FILL, framing_box
    from rh_dataset.render.passes import render_frame
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import load_mitsuba, select_variant

    select_variant(None)
    env = studio_environment(load_mitsuba())
    test = next(x for x in load_protocol("protocol_a").splits if x.name == "test")
    settings = render_settings(args.preset, spp=args.spp).for_split(test)
    recipes = benchmark_recipes("protocol_a", args.seed)
    layers = ["image", "albedo", "mask"]
    print(f"load average at start: {' '.join(open('/proc/loadavg').read().split()[:3])}; {args.preset} preset, "
          f"{settings.spp} spp, AOV {settings.aov_spp} spp, depth {settings.max_depth}; {BROW_HAIRS} hairs a brow")
    rows = []
    for s in (int(x) for x in args.subjects.split(",")):
        r = recipes[s]
        feats = body_features(r.phenotype)
        character = build_character(r)
        generated = pose_character(character)
        brows = [m for m in generated if m.name.startswith("brows")]  # the generator's (character.FACE_HAIR)
        posed = [m for m in generated if not m.name.startswith("brows")]
        at = next(i for i, m in enumerate(posed) if m.name == "body")
        body = posed[at]
        # The build's skin (no brows painted) and the same with them painted (its streams: character._STREAM_SKIN*).
        skins = {paint: skin_texture(r.skin, r.hair.colour, feats, np.random.default_rng([r.seed, _STREAM_SKIN]),
                                     body.material.albedo.shape[0], brows=paint,
                                     detail_rng=np.random.default_rng([r.seed, _STREAM_SKIN_DETAIL]))
                 for paint in (True, False)}
        if not np.array_equal(skins[False], body.material.albedo):
            raise SystemExit(f"subject {s}: the skin texture rebuilt here is not the character's")
        t0 = time.perf_counter()
        build_brows(feats, np.random.default_rng([r.seed, _STREAM_FACE_HAIR]))  # what the build spends on them
        t_brows = time.perf_counter() - t0
        lashes = build_lashes(feats, np.random.default_rng([r.seed, _STREAM_FACE_HAIR, 1]))
        painted = list(posed)
        painted[at] = dataclasses.replace(body, material=dataclasses.replace(body.material, albedo=skins[True]))
        with_brows = posed + brows
        # The lashes posed as the build's strands are (dealt to the hair's fibres, anchored by pose_character).
        dealt = _split_fibres(lashes, fibres_for_colour(r.hair.colour),
                              np.random.default_rng([r.seed, _STREAM_FACE_HAIR, 2]), "lashes")
        with_lashes = with_brows + [m for m in pose_character(dataclasses.replace(character, strands=dealt))
                                    if m.name.startswith("lashes")]
        variants = {"painted": (painted, 1), "painted2": (painted, 2), "brows": (with_brows, 1),
                    "lashes": (with_lashes, 1)}
        lo, hi = body_bounds(posed)
        head = body.vertices[body.vertices[:, 2] > feats.bone_heads["eye.L"][2] - 0.14].astype(np.float64)
        hlo, hhi = head.min(0), head.max(0)
        hlo[0], hhi[0] = min(hlo[0], hlo[1]), max(hhi[0], hhi[1])  # a square-ish box round the head
        cams = {"protocol": frame_body(*framing_box(lo, hi), 512, 512, 30.0, fill=CAMERA_FILL),
                "close-up": frame_body(hlo, hhi + [0, 0, 0.03], 512, 512, 30.0, fill=args.closeup_fill)}
        brow_pts = np.concatenate([m.points.reshape(-1, 3) for m in brows]).astype(np.float64)
        lash_pts = next(m for m in with_lashes if m.name == "lashes").points.reshape(-1, 3).astype(np.float64)
        print(f"subject {s}: hair colour (sRGB) {tuple(round(c, 2) for c in r.hair.colour)}, headwear "
              f"{','.join(h.kind for h in r.headwear) or 'none'}; {len(brow_pts) // POINTS} brow hairs, "
              f"{lashes.rest.shape[0]} lashes (bound within {1e3 * bind_error(lashes, feats):.3f} mm); growing the "
              f"brows {t_brows:.2f} s")
        crops = []
        for name, cam in ((k, cams[k]) for k in args.framings):
            img, alb = {}, {}
            times = {k: [] for k in variants}
            for rnd in range(1 + args.repeats):  # round 0 compiles each scene's kernels; the others are timed
                for label, (meshes, seed) in variants.items():  # interleaved: a load change hits every variant
                    t0 = time.perf_counter()
                    out = render_frame(meshes, env, cam, settings, layers, seed=seed).layers
                    if rnd:
                        times[label].append(time.perf_counter() - t0)
                    img[label], alb[label] = out["image"], out["albedo"]
            secs = {k: float(np.median(v)) for k, v in times.items()}
            shape = img["painted"].shape
            brow_px, (x0, y0, x1, y1) = _box(cam, brow_pts, shape, 2)
            lash_px, _ = _box(cam, lash_pts, shape, 2)
            z = float(np.median(brow_pts[:, 1]) - cam.origin[1])
            mm = 2000.0 * z * np.tan(np.radians(15.0)) / 512
            print(f"  {name:9s} {mm:.2f} mm/px at the brows; boxes {x1 - x0}x{y1 - y0} px (brows), "
                  f"{int(lash_px.sum())} px (lashes); load {os.getloadavg()[0]:.2f}")
            for what, px, a, b in (("brows", brow_px, "brows", "painted"), ("lashes", lash_px, "lashes", "brows")):
                print(f"    {what:6s} PSNR {a} vs {b} {_psnr(img[a], img[b], px):5.1f} dB, two painted seeds "
                      f"{_psnr(img['painted2'], img['painted'], px):5.1f} dB | albedo mean |diff| "
                      f"{np.abs(alb[a] - alb[b])[px].mean():.4f}, seeds "
                      f"{np.abs(alb['painted2'] - alb['painted'])[px].mean():.4f}")
            print("    frame s: " + ", ".join(f"{k} {v:.1f}" for k, v in secs.items()), flush=True)
            cx, cy = (x0 + x1) // 2, (y0 + y1) // 2
            half = max(x1 - x0, 24) // 2 + 4 if name == "protocol" else 128
            ya, xa = max(cy - half // 2, 0), max(cx - half, 0)

            def crop(a):
                c = a[ya:ya + half + (half // 2 if name == "protocol" else 64), xa:xa + 2 * half]
                k = 4 if name == "protocol" else 1
                return np.repeat(np.repeat(c, k, 0), k, 1)

            pic = np.concatenate([np.concatenate([crop(img[k] * 1.3) for k in ("painted", "brows", "lashes")], 1),
                                  np.concatenate([crop(alb[k]) for k in ("painted", "brows", "lashes")], 1)], 0)
            crops.append(pic)
        w = max(c.shape[1] for c in crops)
        rows.append(np.concatenate([np.pad(c, ((0, 4), (0, w - c.shape[1]), (0, 0))) for c in crops], 0))
    if args.figure is not None:
        w = max(x.shape[1] for x in rows)
        fig = np.concatenate([np.pad(x, ((0, 0), (0, w - x.shape[1]), (0, 0))) for x in rows], 0)
        write_png(args.figure, quantize8(srgb_encode(np.clip(fig, 0, 1))))
        print(f"wrote {args.figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
