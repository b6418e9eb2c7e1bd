"""Close-ups of the eyes: benchmark subjects with different iris colours, front and three-quarter, at 512x512.

    python bench/eyes_gallery.py [--out docs/eyes.png] [--size 512] [--spp 32] [--subjects 4]

Subjects: the first benchmark-seed recipes (seeds 2, 4, ...) whose iris classes differ
(`recipe_draws.IRIS_COLOUR_NAMES`, nearest palette colour), unmodified. Each column is a subject; rows: front, the
three-quarter view from the subject's left, and (first column only, the rest left black) the front view without the
eyeballs (what every subject looked like before). The camera is 32 cm from the eyes with a 15 degree field of view
(about 0.15 mm per pixel at 512); dataset renderer (`render_frame`), Blender's studio HDRI, exposure 1.3, rest pose.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the bench folder's modules
from subjects_gallery import studio_environment  # noqa: E402



def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("docs/eyes.png"),
                   help="PNG written (default docs/eyes.png, relative to the working directory)")
    p.add_argument("--size", type=int, default=512, help="width and height in pixels of each close-up (default 512)")
    p.add_argument("--spp", type=int, default=32, help="samples per pixel of each close-up (default 32)")
    p.add_argument("--subjects", type=int, default=4,
                   help="columns: the first benchmark recipes (seeds 2, 4, ...) whose iris classes differ, "
                        "glasses wearers skipped (default 4)")
    args = p.parse_args()

    from rh_common.camera import Camera
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import build_character, pose_character, recipe_from_seed
    from rh_dataset.characters.recipe_draws import iris_colour_name as iris_class
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import load_mitsuba, select_variant

    select_variant(None)
    mi = load_mitsuba()
    env = studio_environment(mi)  # the galleries' light (subjects_gallery.py)
    picks, seen, k = [], set(), 0
    while len(picks) < args.subjects:
        k += 1
        r = recipe_from_seed(2 * k, "benchmark", k)
        if iris_class(r.eyes.iris) not in seen and not any(h.kind == "glasses" for h in r.headwear):
            seen.add(iris_class(r.eyes.iris))
            picks.append(r)
    columns = []
    for i, recipe in enumerate(picks):
        t = time.perf_counter()
        ch = build_character(recipe, 1024)
        posed = pose_character(ch)
        eyes = next(m for m in posed if m.name == "eyes").vertices
        n = len(eyes) // 2
        c = 0.5 * (eyes[:n].mean(0) + eyes[n:].mean(0)) + np.array([0.0, -0.01, -0.004])
        views = [("front", [0.0, -0.32, 0.02]), ("three-quarter", [0.2, -0.25, 0.02])]
        rows = []
        for name, offset in views:
            cam = Camera(args.size, args.size, 15.0, tuple(map(float, c + offset)), tuple(map(float, c)))
            out = render_frame(posed, env, cam, RenderSettings(spp=args.spp, aov_spp=4, max_depth=8), ["image"],
                               seed=i)
            rows.append(quantize8(srgb_encode(np.clip(out.layers["image"] * 1.3, 0.0, None))))
        if i == 0:
            cam = Camera(args.size, args.size, 15.0, tuple(map(float, c + views[0][1])), tuple(map(float, c)))
            out = render_frame([m for m in posed if m.name != "eyes"], env, cam,
                               RenderSettings(spp=args.spp, aov_spp=4, max_depth=8), ["image"], seed=i)
            rows.append(quantize8(srgb_encode(np.clip(out.layers["image"] * 1.3, 0.0, None))))
        else:
            rows.append(np.zeros_like(rows[0]))
        print(f"seed {recipe.seed:<20d} iris {iris_class(recipe.eyes.iris):10s} melanin {recipe.skin.melanin:.2f} "
              f"hair {recipe.hair.style:9s} {time.perf_counter() - t:.1f} s", flush=True)
        columns.append(np.concatenate(rows, 0))
    write_png(args.out, np.concatenate(columns, 1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
