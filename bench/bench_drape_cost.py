"""What loose garments cost the benchmark: drape seconds per kind and level, posing seconds per frame, how many
subjects of each protocol wear them, and the arithmetic for the demo, the default test suite and the full benchmark.

    python bench/bench_drape_cost.py              # ~8 min on a busy 2-core box (three full drapes, three coarse)
    python bench/bench_drape_cost.py --kinds draped_trousers    # time one kind's drapes only
    python bench/bench_drape_cost.py --kinds draped_coat
    python bench/bench_drape_cost.py --kinds draped_hoodie
    python bench/bench_drape_cost.py --kinds draped_jacket
    python bench/bench_drape_cost.py --kinds draped_tshirt
    python bench/bench_drape_cost.py --kinds draped_longsleeve
    python bench/bench_drape_cost.py --kinds draped_shorts draped_straight_trousers
    python bench/bench_drape_cost.py --posing-only --repeats 7  # the per-frame posing only (drapes from the cache)

In: the dataset seed (default 0, the generator's and rh-demo's). Out, printed with the load average: (1) for the
first dress, skirt, wide-trousers, coat, hoodie, open-jacket, loose-t-shirt, loose-long-sleeve, loose-shorts and
straight-trousers wearer of the seed (`--kinds`), the drape's wall
seconds at each level (`drape.DRAPE_LEVELS`; a cold cache in a temporary folder, Warp kernels compiled first by a
one-step drape), and the skinned posing of a walk frame (`pose_character`, the draft and standard presets' cloth
mode) against the first subject in shell clothes; (2) per protocol, its subjects wearing each of those kinds (a
subject may wear up to three: a draped bottom, a loose top, the open jacket; each counted);
(3) the totals: drapes run once per (phenotype, kind, level) and are cached, so a protocol pays each loose subject's
drape once, and protocols of one seed share subjects (and their cache).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

KINDS = ("draped_dress", "draped_skirt", "draped_trousers", "draped_coat", "draped_hoodie", "draped_jacket",
         "draped_tshirt", "draped_longsleeve", "draped_shorts", "draped_straight_trousers")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0,
                    help="dataset seed whose subjects are drawn (rh-generate --seed; default 0, the generator's "
                         "and rh-demo's)")
    ap.add_argument("--protocols", nargs="+", default=["demo", "a", "b", "c"],
                    help="protocols tabulated (a, b, c, demo, another name in rh_dataset/scenes/ or a scene JSON "
                         "path); the subjects drawn are as many as the largest one has")
    ap.add_argument("--kinds", nargs="+", default=list(KINDS), help=f"draped kinds timed (of {KINDS})")
    ap.add_argument("--posing-only", action="store_true",
                    help="time the per-frame posing only, with the drapes from the usual cache (RH_DRAPE_CACHE or "
                         "~/.cache; draped there first if missing, untimed)")
    ap.add_argument("--repeats", type=int, default=3, help="posings per subject whose median is printed")
    args = ap.parse_args(argv)

    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character, sample_recipe
    from rh_dataset.characters.drape import (DRAPE_LEVELS, drape_garment, drape_layers, draped_over, draped_pieces,
                                             drape_settings, piece_settings)
    from rh_dataset.generate.seeding import rng_for
    from rh_dataset.poses import sample_poses
    from rh_dataset.spec import load_protocol

    load = lambda: " ".join(open("/proc/loadavg").read().split()[:3])  # noqa: E731
    n_max = max(load_protocol(p).subjects for p in args.protocols)
    recipes = [sample_recipe(rng_for(args.seed, "character", s), pool="benchmark", index=s) for s in range(n_max)]
    worn = [tuple(g.kind for g in r.garments if g.kind in KINDS) for r in recipes]
    loose = [w[0] if w else None for w in worn]  # the first draped kind (the subject wearing a kind: `wears`)
    wears = {k: [s for s, w in enumerate(worn) if k in w] for k in KINDS}

    print(f"seed {args.seed}; load at start {load()}")
    first = {k: wears[k][0] for k in args.kinds if wears[k]}
    secs = {}
    if not args.posing_only:
        os.environ["RH_DRAPE_CACHE"] = tempfile.mkdtemp(prefix="bench_drape_cost_")  # cold: every drape is timed
        ph0 = recipes[next(iter(first.values()))].phenotype
        t = time.perf_counter()
        drape_garment("draped_skirt", ph0, dataclasses.replace(drape_settings("draped_skirt"), steps=1),
                      use_cache=False)
        print(f"Warp/newton kernels (one-step drape, compiled or loaded): {time.perf_counter() - t:.1f} s")
    for kind, s in first.items():
        for level in DRAPE_LEVELS if not args.posing_only else ():
            ph = recipes[s].phenotype
            # The draped cloth under it (a loose top's skirt), draped first as the build drapes it, not timed; then
            # each of its draped pieces (the hoodie's body, then its hood over it), timed together.
            draped = drape_layers(worn[s][:worn[s].index(kind)], ph, level, worn=worn[s])
            sts = [piece_settings(p, level, worn[s]) for p in draped_pieces(kind)]
            t = time.perf_counter()
            for p, st in zip(draped_pieces(kind), sts):
                draped[p] = drape_garment(p, ph, st, over=draped_over(p, draped))
            secs[kind, level] = time.perf_counter() - t
            grid = " + ".join(f"{st.n_around}x{st.n_rings} particles, {st.steps} steps" for st in sts)
            print(f"subject {s:2d} {kind:13s} {level:6s} {grid}: drape {secs[kind, level]:6.1f} s  (load {load()})",
                  flush=True)
    pose = next(p for p in sample_poses(np.random.default_rng(7), load_anny(), 8) if p.label == "walk")
    for kind, s in first.items():
        r = recipes[s]
        ch = build_character(r, 64, drape="full")
        bare = build_character(recipes[loose.index(None)], 64)  # the first subject in shell clothes only
        times, cpu = {}, {}
        for name, c in (("with", ch), ("without", bare)):
            ts, cs = [], []
            for _ in range(args.repeats):
                t, tc = time.perf_counter(), time.process_time()
                pose_character(c, dict(pose.bones), pose.root_transform)
                ts.append(time.perf_counter() - t)
                cs.append(time.process_time() - tc)
            times[name], cpu[name] = statistics.median(ts), statistics.median(cs)
        print(f"subject {s:2d} {kind:13s} posing a walk frame (skinned, median of {args.repeats}): {times['with']:.2f} s "
              f"({cpu['with']:.2f} CPU s), subject {loose.index(None)} in shell clothes {times['without']:.2f} s "
              f"({cpu['without']:.2f} CPU s)  (load {load()})")
        secs[kind, "pose"] = times["with"] - times["without"]

    print("\nprotocol        subjects  dresses  skirts  trousers  coats  hoodies  jackets  tshirts  sleeves  shorts  "
          "straight  frames/subject  "
          "drape (full / coarse)   posing added"
          f"  (kinds timed: {', '.join(first)})")
    for p in args.protocols:
        spec = load_protocol(p)
        n = {k: sum(s < spec.subjects for s in wears[k]) for k in KINDS}
        frames = sum(sp.frames for sp in spec.splits)
        full = sum(n[k] * secs.get((k, "full"), 0.0) for k in KINDS)
        coarse = sum(n[k] * secs.get((k, "coarse"), 0.0) for k in KINDS)
        posing = sum(n[k] * secs.get((k, "pose"), 0.0) for k in KINDS) * frames
        print(f"{p:14s} {spec.subjects:9d} {n['draped_dress']:8d} {n['draped_skirt']:7d} {n['draped_trousers']:9d}"
              f" {n['draped_coat']:6d} {n['draped_hoodie']:8d} {n['draped_jacket']:8d} {n['draped_tshirt']:8d} {n['draped_longsleeve']:8d}"
              f" {n['draped_shorts']:7d} {n['draped_straight_trousers']:9d} {frames:15d}  "
              + (f"{full / 60:7.1f} / {coarse / 60:5.1f} min" if not args.posing_only else f"{'(not timed)':>19s}")
              + f"  {posing / 3600:9.2f} h (if every frame "
              "posed as the walk)")
    print(f"(load at the end {load()})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
