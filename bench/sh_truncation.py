"""Order-2 SH irradiance vs brute-force cosine convolution, per environment map, at full map resolution.

    python bench/sh_truncation.py [--folder DIR] [--normals N] [--no-sunsky]

For each map: relative error |E_sh(n) − E(n)| / E(n) over N Fibonacci-sphere normals (luminance): mean, p95, max;
the same errors relative to the map's mean irradiance (max %); and the largest ratio of the error to its rigorous
bound (3/32)·∫L dω / E(n) (must be ≤ 1). Maps are used as loaded (negatives clamped), unscaled and unrotated
(rotation and scale do not change relative errors).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from rh_common import sh
from rh_dataset.lights import bake_sunsky, hdri_library, load_hdri, sh_truncation_error


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--folder", default=None, help="folder of .exr/.hdr maps (default: the bundled HDRIs)")
    ap.add_argument("--normals", type=int, default=1000)
    ap.add_argument("--no-sunsky", action="store_true")
    args = ap.parse_args(argv)

    maps: list[tuple[str, np.ndarray]] = []
    for name, path in hdri_library(args.folder).items():
        maps.append((name, load_hdri(path)[0]))
    if not args.no_sunsky:
        maps.append(("sunsky(az30,el40,t3)", bake_sunsky(30.0, 40.0, 3.0)))
        maps.append(("sunsky(az30,el15,t2)", bake_sunsky(30.0, 15.0, 2.0)))
    normals = sh.fibonacci_sphere(args.normals)
    print(f"{args.normals} normals, full resolution; errors in % (luminance)")
    print(f"{'map':24s} {'size':>9s} {'mean':>7s} {'p95':>7s} {'max':>7s} {'max/meanE':>9s} {'max err/bound':>13s}")
    for name, radiance in maps:
        t0 = time.perf_counter()
        te = sh_truncation_error(radiance, normals)
        dt = time.perf_counter() - t0
        H, W = radiance.shape[:2]
        print(f"{name:24s} {W:4d}x{H:<4d} {100 * te.mean:7.2f} {100 * te.p95:7.2f} {100 * te.max:7.2f} "
              f"{100 * float(te.relative_to_mean.max()):9.2f} {float(np.max(te.relative / te.bound)):13.3f}"
              f"   ({dt:.1f} s)")


if __name__ == "__main__":
    main()
