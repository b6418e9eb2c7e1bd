"""The eyeball fit over benchmark subjects: where the ball sits, how big, how far it reaches into the lids, and the
worst poke through the lids in the rest pose.

    python bench/eyes_fit.py [--subjects 12] [--seed 0]

In: protocol_a's benchmark subjects as rh-generate draws them at `--seed` (the first N). Out (stdout), per subject
and as ranges: the centre's offset from anny's `eye.L` joint (mm; x > 0 lateral, z > 0 up), the radius, the
farthest lid inner edge and the nearest front edge seen from the centre on both sides (`eyes.socket_rim`), the gaze's
downward tilt, and the worst `eyes.lid_penetration` of either ball in the rest pose; the seconds the fit took.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--subjects", type=int, default=12,
                   help="how many subjects: the first N that rh-generate draws for protocol_a (default 12)")
    p.add_argument("--seed", type=int, default=0,
                   help="dataset seed the subjects are drawn at (rh-generate --seed; default 0)")
    args = p.parse_args()

    from rh_dataset.characters import sample_recipe
    from rh_dataset.characters.body import body_topology
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.eyes import MIRROR, eye_geometry, lid_penetration, socket_rim
    from rh_dataset.generate.seeding import rng_for
    from rh_dataset.spec import load_protocol

    spec = load_protocol("protocol_a")
    faces = body_topology().faces
    fwd, up = np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    rows = []
    print("subject  offset x,z mm   radius  inner max  front min  tilt deg  poke mm  fit s")
    for s in range(args.subjects):
        r = sample_recipe(rng_for(args.seed, "character", s), pool=spec.character_pool, index=s)
        feats = body_features(r.phenotype)
        t = time.perf_counter()
        g = eye_geometry(feats)
        dt = time.perf_counter() - t
        f = g.fit
        n = len(g.vertices) // 2
        inner, front, poke = [], [], []
        for sl, m in ((slice(0, n), np.ones(3)), (slice(n, None), MIRROR)):
            rim = socket_rim(feats.rest_vertices, faces, f.centre * m, fwd, up)
            inner.append(np.linalg.norm(rim.inner - f.centre * m, axis=1).max())
            front.append(np.linalg.norm(rim.front - f.centre * m, axis=1).min())
            poke.append(lid_penetration(feats.rest_vertices, faces, f.centre * m, g.vertices[sl]).max())
        off = (f.centre - feats.bone_heads["eye.L"]) * 1000
        row = (off[0], off[2], f.radius * 1000, max(inner) * 1000, min(front) * 1000,
               -np.degrees(np.arcsin(f.gaze[2])), max(poke) * 1000)
        rows.append(row)
        print(f"{s:7d}  {row[0]:+5.1f} {row[1]:+5.1f}   {row[2]:6.2f}  {row[3]:9.2f}  {row[4]:9.2f}  {row[5]:8.1f}  "
              f"{row[6]:7.3f}  {dt:5.1f}", flush=True)
    a = np.array(rows)
    names = ("offset x mm", "offset z mm", "radius mm", "inner max mm", "front min mm", "tilt down deg", "poke mm")
    for k, name in enumerate(names):
        print(f"{name:14s} min {a[:, k].min():7.2f}  max {a[:, k].max():7.2f}")
    print(f"vertices per character: {len(g.vertices)}")


if __name__ == "__main__":
    main()
