"""Do two renders with the same seed give the same bits? Mitsuba's film against the focused pass's pixel list.

    python bench/bench_repeatability.py [--size 96] [--spp 4 9 12 16 25 64 99 100] [--runs 4]

Renders a sphere under a constant light (path depth 3, multijitter) `--runs` times per sample count with
`mi.render` and with `rh_dataset.render.focus.render_pixels` on every pixel, and prints whether every run equals
the first. Mitsuba's film adds samples into pixels with a scatter-add whose order depends on which thread took which
of drjit's 16384-lane blocks, so a pixel whose samples straddle two blocks may get other last bits; `render_pixels`
sums each pixel's samples in a fixed order. Prints a Markdown table.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=96, help="image width and height in pixels (default 96)")
    p.add_argument("--spp", type=int, nargs="+", default=[4, 9, 12, 16, 25, 64, 99, 100],
                   help="sample counts rendered, a table row each")
    p.add_argument("--runs", type=int, default=4,
                   help="renders per sample count by mi.render and by render_pixels, each compared with the first "
                        "(default 4)")
    args = p.parse_args()

    from analytic_scenes import uv_sphere
    from rh_common.camera import Camera
    from rh_dataset.render.focus import render_pixels
    from rh_dataset.render.scene import scene_dict
    from rh_dataset.variant import load_mitsuba, select_variant

    select_variant("llvm_ad_rgb")
    mi = load_mitsuba()
    n = args.size
    cam = Camera(width=n, height=n, fov_y_deg=50.0, origin=(0.0, -4.0, 0.3), target=(0.0, 0.0, 0.0))
    env = {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 0.8, 0.6]}}
    pix = np.arange(n * n, dtype=np.uint32)
    load = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    print(f"{n}x{n}, {args.runs} runs per count, load average {load}\n")
    print("| spp | lanes | mi.render runs repeat | render_pixels runs repeat |\n|---|---|---|---|")
    for spp in args.spp:
        scene = mi.load_dict(scene_dict([uv_sphere()], env, cam, {"type": "path", "max_depth": 3}, spp,
                                        pixel_format="rgba", sampler="multijitter"))
        film = [np.array(mi.render(scene, spp=spp, seed=9), dtype=np.float32) for _ in range(args.runs)]
        mine = [render_pixels(mi, scene, pix, spp, 9) for _ in range(args.runs)]
        same_film = sum(np.array_equal(film[0], f) for f in film[1:])
        same_mine = sum(np.array_equal(mine[0], m) for m in mine[1:])
        print(f"| {spp} | {n * n * spp} | {same_film} of {args.runs - 1} | {same_mine} of {args.runs - 1} |", flush=True)


if __name__ == "__main__":
    main()
