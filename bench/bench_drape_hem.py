"""Where a draped kind's hem settles on a few builds, against the hip joints and the crotch: how its cut was chosen.

    python bench/bench_drape_hem.py                                   # the open jacket, both levels, its own cut
    python bench/bench_drape_hem.py --hem 0.08 0.15 --levels coarse   # other cuts (DrapeProfile.hem)
    python bench/bench_drape_hem.py --kind draped_coat
    python bench/bench_drape_hem.py --kind draped_straight_trousers   # legged kinds: the hems against floor, ankles

In: a draped kind cut by a `drape.DrapeProfile` (default `draped_jacket`), the cuts tried (`--hem`: the profile's
`hem`, replaced for the run; default the kind's own), the drape levels. Builds: a slim woman and a heavy man (the
drape tests' PHENO and HEAVY), a thin tall man and a heavy short woman. Out, printed per (cut, build, level) with the
load average: the pinned ring's height, the hip joints' (upperleg01, mean of both sides), the crotch's (the lowest
point of the body's underside on the midplane, `drape._crotch_height`), the pattern's hem and the settled hem (mean,
min, max of the last ring) and its distance from the hip joints and the crotch (metres, A-pose frame), the deepest
particle (mm, < 0 outside the body) and the drape's wall seconds (0 when the drape cache held it: RH_DRAPE_CACHE or
~/.cache). For a kind with legs (`DrapeProfile.legs`: trousers, shorts) the settled hem is both legs' last rings,
measured against the floor (the body's lowest point), the ankle joints (foot, mean of both sides) and the knee
joints (lowerleg01) instead, and the cut is the kind's own (its `hem` is metres over the floor, or `leg_hem`).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BUILDS = {"slim woman": {"gender": 1.0, "age": 0.6, "muscle": 0.5, "weight": 0.5, "height": 0.5, "proportions": 0.5},
          "heavy man": {"gender": 0.0, "age": 0.6, "muscle": 0.5, "weight": 0.95, "height": 0.5, "proportions": 0.5},
          "thin tall man": {"gender": 0.0, "age": 0.4, "muscle": 0.3, "weight": 0.1, "height": 0.8,
                            "proportions": 0.5},
          "heavy short woman": {"gender": 1.0, "age": 0.7, "muscle": 0.3, "weight": 0.9, "height": 0.3,
                                "proportions": 0.5}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", default="draped_jacket",
                    help="draped kind measured, one cut by a drape.DrapeProfile (drape.PROFILES), e.g. draped_coat, "
                         "draped_skirt, draped_straight_trousers (default draped_jacket)")
    ap.add_argument("--hem", type=float, nargs="*", default=[], help="cuts tried (DrapeProfile.hem); default its own")
    ap.add_argument("--levels", nargs="+", default=["full", "coarse"],
                    help="drape levels measured (drape.DRAPE_LEVELS: full, coarse; default both)")
    args = ap.parse_args(argv)

    import trimesh

    from rh_dataset.characters import drape
    from rh_dataset.characters.body import body_topology, run_anny

    load = lambda: " ".join(open("/proc/loadavg").read().split()[:3])  # noqa: E731
    own = drape.PROFILES[args.kind]
    if own.legs and args.hem:
        ap.error(f"--hem: {args.kind} is cut by its own profile (metres over the floor or leg_hem), not tried here")
    for hem in args.hem or [own.hem]:
        drape.PROFILES[args.kind] = dataclasses.replace(own, hem=hem)
        for level in args.levels:
            st = drape.drape_settings(args.kind, level)
            for name, ph in BUILDS.items():
                run = run_anny(ph)
                heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
                hip = 0.5 * float(heads["upperleg01.L"][2] + heads["upperleg01.R"][2])
                mesh = trimesh.Trimesh(run["vertices"], drape.collider_faces(ph), process=False)
                crotch = drape._crotch_height(mesh, np.asarray(heads["root"], np.float64), hip + 0.1)
                t = time.perf_counter()
                g = drape.drape_garment(args.kind, ph, st)
                secs = time.perf_counter() - t
                depth = drape.penetration(run["vertices"], body_topology().faces, g.vertices).max()
                if g.pieces:  # trousers, shorts: both legs' last rings
                    hems = np.concatenate([p[-1] for p in g.pieces[1:]])
                    last, cut = g.vertices[hems, 2], float(g.pattern[hems, 2].mean())
                    joint = {b: 0.5 * float(heads[f"{b}.L"][2] + heads[f"{b}.R"][2]) for b in ("foot", "lowerleg01")}
                    floor = float(run["vertices"][:, 2].min())
                    print(f"{level:6s} {name:17s} pattern hem {cut:+.3f} settled {last.mean():+.3f} "
                          f"({last.min():+.3f}..{last.max():+.3f}): {100 * (cut - last.mean()):4.1f} cm under the cut, "
                          f"{100 * (last.mean() - floor):4.1f} cm over the floor, "
                          f"{100 * (last.mean() - joint['foot']):+5.1f} cm over the ankle joints, "
                          f"{100 * (last.mean() - joint['lowerleg01']):+5.1f} cm over the knee joints; deepest "
                          f"{1e3 * depth:6.1f} mm; drape {secs:5.1f} s  (load {load()})", flush=True)
                    continue
                last = g.vertices[-st.n_around:, 2]
                print(f"hem {hem:.2f} {level:6s} {name:17s} ring {g.vertices[0, 2]:+.3f} hips {hip:+.3f} crotch "
                      f"{crotch:+.3f} pattern hem {g.pattern[-1, 2]:+.3f} settled {last.mean():+.3f} "
                      f"({last.min():+.3f}..{last.max():+.3f}): {100 * (hip - last.mean()):4.1f} cm under the hips, "
                      f"{100 * (last.mean() - crotch):+5.1f} cm above the crotch; deepest {1e3 * depth:6.1f} mm; "
                      f"drape {secs:5.1f} s  (load {load()})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
