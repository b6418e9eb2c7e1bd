"""Gallery of the hair styles and colours on benchmark subjects: head-and-shoulders renders (beauty, albedo layer).

    python bench/subjects_gallery.py [--out docs/subjects.png] [--size 256] [--spp 64]
    python bench/subjects_gallery.py --headwear [--out docs/headwear.png] [--size 512] [--spp 20]

--headwear: the first two benchmark-seed subjects (seeds 2, 4, ...) whose recipe draws each headwear kind (cap,
brimmed_hat, headscarf, glasses), unmodified (their own hair, clothes and headwear colours), one column per kind,
beauty only, from the front-left (top row) and the left (bottom row).

Each tile is a benchmark subject (recipe from an even seed) with its hair style and colour replaced so that every
style (rh_dataset.characters.HAIR_STYLES) appears once, colours cycling through black, brown, blonde, auburn and
grey. Rendered by the dataset renderer (`render_frame`: path tracer + AOV pass) in the rest pose under Blender's
studio HDRI, seen from the front-left. Top row: the beauty image (sRGB, exposure 1.3); bottom: the albedo layer.
"""
from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

STUDIO_HDRI = Path("/usr/share/blender/datafiles/studiolights/world/studio.exr")
COLOURS = {"black": (20, 16, 14), "brown": (80, 54, 36), "blonde": (205, 170, 110), "auburn": (130, 60, 32),
           "grey": (170, 168, 165)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("docs/subjects.png"))
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--headwear", action="store_true", help="the headwear gallery instead of the hair one")
    args = p.parse_args()

    from rh_common.camera import Camera
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import HAIR_STYLES, HairSpec, build_character, pose_character, recipe_from_seed
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import load_mitsuba, select_variant

    select_variant(None)
    mi = load_mitsuba()
    env = {"type": "envmap", "filename": str(STUDIO_HDRI),
           "to_world": mi.ScalarTransform4f().rotate([0, 0, 1], 200).rotate([1, 0, 0], 90)}
    if args.headwear:
        return _headwear(args, env)
    names = list(COLOURS)
    tiles = []
    for k, style in enumerate(HAIR_STYLES):
        colour = names[k % len(names)]
        recipe = recipe_from_seed(2 * (k + 1), "benchmark", k)
        recipe = dataclasses.replace(recipe, hair=HairSpec(style, tuple(c / 255 for c in COLOURS[colour])))
        t = time.perf_counter()
        posed = pose_character(build_character(recipe, 512))
        hair = np.concatenate([m.vertices for m in posed if hasattr(m, "fibre")])
        c = np.array([np.median(hair[:, 0]), np.median(hair[:, 1]), hair[:, 2].max() - 0.17])
        cam = Camera(args.size, args.size, 30.0, tuple(map(float, c + [0.4, -0.8, 0.08])), tuple(map(float, c)))
        out = render_frame(posed, env, cam, RenderSettings(spp=args.spp, aov_spp=16, max_depth=8),
                           ["image", "albedo"], seed=k)
        print(f"{style:10s} {colour:7s} {sum(len(m.points) for m in posed if hasattr(m, 'fibre'))} strands, "
              f"{time.perf_counter() - t:.1f} s", flush=True)
        img = quantize8(srgb_encode(np.clip(out.layers["image"] * 1.3, 0.0, None)))
        alb = quantize8(srgb_encode(out.layers["albedo"]))
        tiles.append(np.concatenate([img, alb], 0))
    write_png(args.out, np.concatenate(tiles, 1))
    print(f"wrote {args.out}")


def _headwear(args, env) -> None:
    from rh_common.camera import Camera
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import build_character, pose_character, recipe_from_seed
    from rh_dataset.characters.recipe import HEADWEAR_KINDS
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings

    picks: dict[str, list] = {k: [] for k in HEADWEAR_KINDS}
    k = 0
    while any(len(v) < 2 for v in picks.values()):
        k += 1
        r = recipe_from_seed(2 * k, "benchmark", k)
        kinds = [h.kind for h in r.headwear]
        main = next((x for x in kinds if x != "glasses"), "glasses" if kinds else None)
        if main is not None and len(picks[main]) < 2:
            picks[main].append(r)
    columns = []
    for kind in HEADWEAR_KINDS:
        rows = []
        for i, recipe in enumerate(picks[kind]):
            t = time.perf_counter()
            posed = pose_character(build_character(recipe, 512))
            body = next(m for m in posed if m.name == "body").vertices
            top = float(body[:, 2].max())
            head = body[body[:, 2] > top - 0.25]
            c = np.array([float(np.median(head[:, 0])), float(np.median(head[:, 1])), top - 0.13])
            offset = [0.4, -0.8, 0.08] if i == 0 else [0.9, -0.05, 0.05]
            cam = Camera(args.size, args.size, 30.0, tuple(map(float, c + offset)), tuple(map(float, c)))
            out = render_frame(posed, env, cam, RenderSettings(spp=args.spp, aov_spp=4, max_depth=8), ["image"],
                               seed=k)
            worn = "+".join(h.kind for h in recipe.headwear)
            print(f"{kind:12s} seed {recipe.seed:<20d} {worn:20s} hair {recipe.hair.style:9s} "
                  f"{time.perf_counter() - t:.1f} s", flush=True)
            rows.append(quantize8(srgb_encode(np.clip(out.layers["image"] * 1.3, 0.0, None))))
        columns.append(np.concatenate(rows, 0))
    write_png(args.out, np.concatenate(columns, 1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
