"""Order-2 SH irradiance vs brute-force cosine convolution, per environment map, at full map resolution.

    python bench/sh_truncation.py [--folder DIR] [--normals N] [--no-sunsky]
    python bench/sh_truncation.py --olat rings16 [--olat-radius 3] [--normals N]

For each map: relative error |E_sh(n) − E(n)| / E(n) over N Fibonacci-sphere normals (luminance): mean, p95, max;
the same errors relative to the map's mean irradiance (max %); and the largest ratio of the error to its rigorous
bound (3/32)·∫L dω / E(n) (must be ≤ 1). Maps are used as loaded (negatives clamped), unscaled and unrotated
(rotation and scale do not change relative errors).

With --olat SET: the OLAT lights of that direction set (rh_dataset.lights.olat, the olat split's lights) instead.
Relative errors per normal mean little there (half the normals receive no light at all), so each row gives, against
E_f, the exact irradiance of a surface facing the light: the SH error at that facing normal, the largest error over
all normals (theory for a point source: 3/32 = 9.4% at grazing), the mean error over all normals, the share of
normals where SH irradiance is negative, and the largest |SH irradiance| on the normals that see none of the light.
Theory for a point source (order-2 clamped cosine K₂(t) = 1/4 + t/2 + (5/32)(3t² − 1)): +6.25% facing, 9.4% at
grazing, negative for t in (−0.824, −0.243), i.e. 29.1% of the sphere; on the dark side up to 9.4% just past the
terminator and 6.25% straight behind.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from rh_common import sh
from rh_common.colourspace import luminance
from rh_dataset.lights import (LightSpec, bake_sunsky, brute_force_irradiance, build_light, hdri_library, load_hdri,
                               olat_directions, olat_params, olat_scale, sh_truncation_error, sun_direction)


def olat_table(direction_set: str, radius_deg: float, n_normals: int) -> None:
    normals = sh.fibonacci_sphere(n_normals)
    print(f"OLAT set {direction_set}, disc radius {radius_deg:g} deg, {n_normals} normals, full resolution; "
          f"errors in % of E_f (luminance)")
    print(f"{'#':>2s} {'az':>6s} {'el':>6s} {'facing':>7s} {'max':>6s} {'mean':>6s} {'E_sh<0':>7s} {'dark side':>9s}")
    rows = []
    for k, (az, el) in enumerate(olat_directions(direction_set)):
        t0 = time.perf_counter()
        p = olat_params(az, el, radius_deg)
        light = build_light(LightSpec("olat", "olat", "", 0.0, olat_scale(p), params=p))
        n = np.concatenate([sun_direction(az, el)[None], normals])  # row 0: the normal facing the light
        e = luminance(brute_force_irradiance(light.radiance, n))
        e_sh = luminance(sh.irradiance(light.sh_world, n))
        e_f = e[0]
        err = np.abs(e_sh - e) / e_f
        dark = e[1:] == 0.0
        row = (100 * (e_sh[0] - e_f) / e_f, 100 * err.max(), 100 * err[1:].mean(), 100 * np.mean(e_sh[1:] < 0),
               100 * float(np.max(np.abs(e_sh[1:][dark]))) / e_f)
        rows.append(row)
        print(f"{k:2d} {az:6.1f} {el:6.1f} {row[0]:+7.2f} {row[1]:6.2f} {row[2]:6.2f} {row[3]:7.1f} {row[4]:9.2f}"
              f"   ({time.perf_counter() - t0:.1f} s)")
    lo, hi = np.min(rows, axis=0), np.max(rows, axis=0)
    print(f"{'range':>16s} " + " ".join(f"{a:+.2f}..{b:+.2f}" for a, b in zip(lo, hi)))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--folder", default=None, help="folder of .exr/.hdr maps (default: the bundled HDRIs)")
    ap.add_argument("--normals", type=int, default=1000,
                    help="Fibonacci-sphere normals the errors are taken over (default 1000)")
    ap.add_argument("--no-sunsky", action="store_true",
                    help="leave out the two baked sunsky maps (sun at azimuth 30 deg, elevation 40 and 15 deg)")
    ap.add_argument("--olat", default=None, metavar="SET", help="OLAT direction set (rings16, fibonacci16) instead")
    ap.add_argument("--olat-radius", type=float, default=3.0, help="OLAT disc radius in degrees (default 3)")
    args = ap.parse_args(argv)
    if args.olat is not None:
        olat_table(args.olat, args.olat_radius, args.normals)
        return

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
