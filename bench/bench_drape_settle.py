"""Is a drape at rest when it ends? What `DrapeSettings.settle` (steps of dynamic relaxation after the drape's
`steps`, each particle keeping `settle_keep` of its velocity from step to step) changes, per draped piece.

    python bench/bench_drape_settle.py                            # every kind's first wearer, full level
    python bench/bench_drape_settle.py --kinds draped_hoodie --settle 50 100 200 --keep 0 0.8

In: the dataset seed (default 0); for the first benchmark subject of the seed wearing each of `--kinds`, the cloth
under it draped as the build drapes it (from the drape cache), then each of the kind's draped pieces
(`draped_pieces`: the hoodie's body, then its hood) draped at `--level` as the build drapes it (its own `settle`) and
again with each `--settle` count and `--keep` fraction, over the same cloth. Out, printed with the load average: per
piece, count and fraction, how far the settle moved the cloth (the largest and the 99th-percentile particle
displacement, and the largest, 99th percentile and median distance of its particles to the surface as built: a fold
that travels round the body moves particles along the surface, which moves the first and not the second; mm), the
cloth's worst depth in the body before and after (mm, `penetration`: negative is outside), and the seconds each drape
took; with `--more N`, how far N more steps move the drape as built and N more settle steps each settled one
(largest, 99th percentile): a drape still swinging where it ends moves by millimetres a step, one at rest by the
solver's residual. (Under a steady force, steps from rest, `--keep 0`, move a cloth ~3x less than steps keeping 0.8
of the velocity and ~5x less than free steps: compare `--more` figures at one fraction.)
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv: list[str] | None = None) -> int:
    from rh_dataset.characters.drape import DRAPE_LEVELS, DRAPED_KINDS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0, help="dataset seed whose benchmark subjects wear the kinds")
    ap.add_argument("--kinds", nargs="+", default=["draped_dress", "draped_skirt", "draped_trousers", "draped_coat",
                                                   "draped_hoodie", "draped_jacket", "draped_tshirt",
                                                   "draped_longsleeve", "draped_shorts",
                                                   "draped_straight_trousers"],
                    help="recipe garment kinds whose first wearer is draped")
    ap.add_argument("--level", default="full", choices=DRAPE_LEVELS, help="drape level")
    ap.add_argument("--settle", nargs="+", type=int, default=[100], help="settle step counts compared")
    ap.add_argument("--keep", nargs="+", type=float, default=[None],
                    help="settle_keep fractions compared (the velocity each particle keeps from one settle step to "
                         "the next; 0: each step from rest); default: each piece's own")
    ap.add_argument("--more", type=int, default=0,
                    help="also drape each with this many more steps (and each settle with this many more settle "
                         "steps) and print how far those moved it: is it still moving where it ends? (0: not)")
    args = ap.parse_args(argv)

    from rh_dataset.characters import sample_recipe
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.drape import (drape_garment, drape_layers, draped_over, draped_pieces,
                                             penetration, piece_settings)
    from rh_dataset.characters.geometry import closest_point, query_mesh
    from rh_dataset.generate.seeding import rng_for

    bad = [k for k in args.kinds if not set(draped_pieces(k)) <= set(DRAPED_KINDS) or not draped_pieces(k)]
    if bad:
        ap.error(f"not draped kinds: {bad}")
    load = lambda: " ".join(open("/proc/loadavg").read().split()[:3])  # noqa: E731
    print(f"seed {args.seed}, level {args.level}; load at start {load()}")
    faces = body_topology().faces
    for kind in args.kinds:
        recipes = (sample_recipe(rng_for(args.seed, "character", s), pool="benchmark", index=s) for s in range(200))
        recipe = next(r for r in recipes if kind in [g.kind for g in r.garments])
        s = recipe.index
        worn = [g.kind for g in recipe.garments]
        ph = recipe.phenotype
        body = run_anny(ph)["vertices"]
        draped = drape_layers(worn[:worn.index(kind)], ph, args.level, worn=worn)
        for p in draped_pieces(kind):
            st = piece_settings(p, args.level, worn)
            t = time.perf_counter()
            base = drape_garment(p, ph, st, use_cache=False, over=draped_over(p, draped))
            t_base = time.perf_counter() - t
            d0 = penetration(body, faces, base.vertices).max()

            def more(st_more, q):  # how far `args.more` more steps (or settle steps) move the drape `q`
                g = drape_garment(p, ph, st_more, use_cache=False, over=draped_over(p, draped))
                step = np.linalg.norm(g.vertices - q, axis=1)
                return f"{1000 * step.max():5.1f} / {1000 * np.percentile(step, 99):5.1f} mm"

            if args.more:
                grown = (dataclasses.replace(st, settle=st.settle + args.more) if st.settle
                         else dataclasses.replace(st, steps=st.steps + args.more))
                print(f"subject {s:2d} {p:24s} as built ({st.steps} steps, settle {st.settle}): {args.more} more "
                      f"steps move it {more(grown, base.vertices)} (largest / 99th percentile)  (load {load()})",
                      flush=True)
            for n, keep in ((n, k) for n in args.settle for k in args.keep):
                st_n = dataclasses.replace(st, settle=n, settle_keep=st.settle_keep if keep is None else keep)
                t = time.perf_counter()
                g = drape_garment(p, ph, st_n, use_cache=False, over=draped_over(p, draped))
                t_n = time.perf_counter() - t
                moved = np.linalg.norm(g.vertices - base.vertices, axis=1)
                # How far the cloth's surface moved, not its particles: a fold travelling round the body moves
                # particles along the surface, which the closest point on the drape as built does not count.
                off = closest_point(query_mesh(base.vertices, base.faces), g.vertices)[1]
                d1 = penetration(body, faces, g.vertices).max()
                print(f"subject {s:2d} {p:24s} settle {st.settle:3d} -> {n:3d} keep {st_n.settle_keep:.2f}: particles "
                      f"moved max {1000 * moved.max():5.1f} / 99th pct {1000 * np.percentile(moved, 99):5.1f} mm, "
                      f"off the surface as built max {1000 * off.max():5.1f} / 99th "
                      f"{1000 * np.percentile(off, 99):5.1f} / median {1000 * np.median(off):4.1f} mm; worst depth in "
                      f"the body "
                      f"{1000 * d0:6.1f} -> {1000 * d1:6.1f} mm; drape {t_base:5.1f} s -> {t_n:5.1f} s  "
                      f"(load {load()})", flush=True)
                if args.more:
                    print(f"subject {s:2d} {p:24s} settle {n} keep {st_n.settle_keep:.2f}: {args.more} more settle "
                          f"steps move it {more(dataclasses.replace(st_n, settle=n + args.more), g.vertices)}  "
                          f"(load {load()})",
                          flush=True)
            draped[p] = drape_garment(p, ph, st, over=draped_over(p, draped))
    print(f"(load at the end {load()})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
