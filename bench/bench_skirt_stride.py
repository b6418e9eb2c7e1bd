"""Draped skirts and dresses skinned into a stride or a lifted knee: does the cloth stay one piece? Before (the
closest-point binding, `drape.bind_to_skeleton`) vs after (`drape.bind_loose`, the weights diffused over the cloth).

    python bench/bench_skirt_stride.py                          # 4 subjects x 3 stride poses, 2 simulated references
    python bench/bench_skirt_stride.py --iterations 0 50 200 800 --reference 0    # choose the diffusion
    python bench/bench_skirt_stride.py --figure docs/skirt_stride.png --cases 6:0 0:4 2:2   # the picture only

Subjects: the protocol's first subjects that wear a draped kind (as rh-generate draws them: `sample_recipe` from
`rng_for(seed, "character", s)`, i.e. `recipe_from_seed`), their garment at the full drape (the standard preset's;
cached). Poses: the first --poses poses of the protocol's test pose source (`sample_pose` from
`rng_for(seed, "pose", s, source, j)`, as `AnnySubjects.pose`) with a stride (the thighs >= 30 degrees apart) or a
lifted knee (a thigh >= 40 degrees off the vertical). Per (subject, pose, binding):
  pinch     `cloth_pose.hem_split`: the hem (the garment's last ring) seen from below, averaged over 1/12 of its
            way around (the drape's folds do not count): how deep its deepest vertex lies inside the convex hull of
            its ground-plane projection (cm). A hem that wraps each leg like a trouser leg folds back between the
            legs: deep; one piece of cloth around both legs: shallow (the rest drape's own: printed per subject).
  deficit   the same hem: 1 - (area it encloses) / (its convex hull's area) (%). Seated poses lay the hem over the
            lap, where its ground-plane projection folds over itself: read the walks.
  raw       worst cloth-vertex depth under the posed skin before push_out (mm; > 0 inside);
  worst/p99 the same after push_out (`drape.penetration`, what a frame renders);
  inward    cloth vertices push_out moved against their cloth's outward normal by more than 5 mm: cloth put behind
            the limb that swung into it (the closest skin of a vertex deep in a lifted thigh is often the thigh's
            underside), where the limb can show through;
  sim       (the first --reference poses) the mean / max vertex distance to newton's simulated cloth
            (`cloth_pose.simulate_into_pose`, the reference preset's way), whose own pinch is printed beside.
  ms        skinning + push_out per frame (the binding itself is made once per character: printed per subject).
The load average is printed with the times: the machine is shared.
--figure: per --cases subject:pose (test pose j of subject s), a 512x512 crop (hips to shins, seen from the
front-left) of the subject as the generator builds it (`AnnySubjects`: standard preset, full drape; body, clothes
and shoes, no hair), before | after (or one column per --iterations); Open Image Denoise on 32 spp: a look, not
a dataset frame.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

STRIDE_DEG = 30.0  # thighs at least this far apart
LIFT_DEG = 40.0  # or a thigh at least this far off the vertical
INWARD = 0.005  # metres against the cloth's outward normal: a pushed vertex counted as put behind the limb


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


def leg_angles(bone_poses: np.ndarray) -> tuple[float, float]:
    """(degrees between the two thighs, the larger thigh's angle off straight down) of a posed anny run."""
    from rh_dataset.characters.body import body_topology

    labels = body_topology().bone_labels
    d = []
    for side in ("L", "R"):
        i, j = labels.index(f"lowerleg01.{side}"), labels.index(f"upperleg01.{side}")
        v = bone_poses[i, :3, 3] - bone_poses[j, :3, 3]
        d.append(v / np.linalg.norm(v))
    spread = float(np.degrees(np.arccos(np.clip(d[0] @ d[1], -1.0, 1.0))))
    lift = float(max(np.degrees(np.arccos(np.clip(-v[2], -1.0, 1.0))) for v in d))
    return spread, lift


def stride_poses(seed: int, subject: int, source: str, phenotype, count: int, limit: int = 150):
    """[(j, pose, archetype, spread, lift)]: the first `count` stride / lifted-knee poses of the subject's source."""
    from rh_common.body_model import load_anny
    from rh_dataset.characters.body import run_anny
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose

    out = []
    for j in range(limit):
        pose = sample_pose(rng_for(seed, "pose", subject, source, j), load_anny())
        spread, lift = leg_angles(run_anny(phenotype, dict(pose.bones))["bone_poses"])
        if spread >= STRIDE_DEG or lift >= LIFT_DEG:
            out.append((j, pose, getattr(pose, "label", "?"), spread, lift))
            if len(out) == count:
                break
    return out


def figure(args) -> int:
    """The before | after sheet (module docstring): rows = cases."""
    import dataclasses

    from scipy.spatial import cKDTree

    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import PosedMesh, pose_character
    from rh_dataset.characters.drape import DRAPED_KINDS, SkinBinding, bind_loose, drape_garment
    from rh_dataset.characters.preview import render_preview
    from rh_dataset.cli import render_settings
    from rh_dataset.generate.plan import DatasetPlan
    from rh_dataset.generate.subjects import AnnySubjects
    from rh_dataset.poses.pose import rotation_about_z
    from rh_dataset.spec import load_protocol

    spec = load_protocol(args.protocol)
    test = next(s for s in spec.splits if s.name == "test")
    source = AnnySubjects(DatasetPlan(out=Path("unused"), spec=spec, settings=render_settings("standard")))
    size, crop = 1024, 512
    rows = []
    for case in args.cases:
        s, j = (int(x) for x in case.split(":"))
        t = time.perf_counter()
        subject = source.subject(s)
        ch = subject.character
        part = next(p for p in ch.parts if p.name in DRAPED_KINDS)
        g = drape_garment(part.name, ch.phenotype, part.drape)
        # The part's vertices are the garment's with a seam column duplicated: map them back (rest pose).
        src = cKDTree(g.vertices).query(pose_character(ch, None, None)[ch.parts.index(part)].vertices)[1]
        variants = []
        for it in args.iterations if args.iterations is not None else [0, -1]:
            b = bind_loose(g, ch.phenotype, iterations=None if it < 0 else it)
            variants.append(dataclasses.replace(ch, parts=list(
                dataclasses.replace(p, skinning=SkinBinding(b.bind[src], b.bones[src], b.weights[src]))
                if p is part else p for p in ch.parts)))
        pose = source.pose(subject, test, j)
        world = rotation_about_z(-35.0) @ pose.root_transform  # seen from its front-left
        tiles = []
        for c in variants:
            posed = [m for m in pose_character(c, dict(pose.bones), world) if isinstance(m, PosedMesh)]
            img = render_preview(posed, width=size, height=size, spp=32, seed=s, denoise=True)
            # Rows from the hips down to the shins: the preview frames the whole body, feet at the bottom.
            top = int(0.30 * size)
            tiles.append(quantize8(srgb_encode(np.clip(img[top:top + crop, (size - crop) // 2:][:, :crop], 0, None)
                                               * 1.3)))
        rows.append(np.concatenate(tiles, axis=1))
        print(f"subject {s} {part.name} test {j} ({getattr(pose, 'label', '?')}): {time.perf_counter() - t:.0f} s "
              f"(load {load()})", flush=True)
    write_png(args.figure, np.concatenate(rows, axis=0))
    print(f"wrote {args.figure}: rows = {args.cases}, columns = diffusion steps "
          f"{args.iterations or [0, -1]} (0: the closest-point binding of before, -1: bind_loose's default)")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", type=int, default=4, help="subjects that wear a draped kind")
    ap.add_argument("--poses", type=int, default=3, help="stride / lifted-knee test poses per subject")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed")
    ap.add_argument("--protocol", default="protocol_a", help="protocol the subjects and test poses come from")
    ap.add_argument("--iterations", type=int, nargs="+", default=None,
                    help="bind_loose diffusion steps to compare (0 = the closest-point binding of before; -1 = "
                         "bind_loose's default for the mesh, drape.loose_iterations; default: 0 -1)")
    ap.add_argument("--reference", type=int, default=2, help="poses (first ones) also simulated as the reference")
    ap.add_argument("--figure", type=Path, default=None, help="write the before | after picture here (only)")
    ap.add_argument("--cases", nargs="+", default=["6:0", "0:4", "2:2"], help="subject:test pose of the figure")
    args = ap.parse_args(argv)
    if args.figure is not None:
        return figure(args)

    from rh_dataset.characters import sample_recipe
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.mesh import vertex_normals
    from rh_dataset.characters.cloth_pose import hem_split, simulate_into_pose
    from rh_dataset.characters.drape import (DRAPED_KINDS, bind_loose, drape_garment, loose_iterations,
                                             drape_settings, penetration, push_out, skin_points)
    from rh_dataset.generate import rng_for
    from rh_dataset.generate.plan import pose_source
    from rh_dataset.spec import load_protocol

    variants = args.iterations if args.iterations is not None else [0, -1]
    spec = load_protocol(args.protocol)
    test = next(s for s in spec.splits if s.name == "test")
    source = pose_source(spec, test)
    faces = body_topology().faces
    print(f"load average at start: {load()}; bindings: diffusion steps {variants} (0 = before, -1 = "
          "bind_loose's default: drape.loose_iterations)")
    rows, refs = [], 0
    s = 0
    found = 0
    while found < args.subjects and s < spec.subjects:
        recipe = sample_recipe(rng_for(args.seed, "character", s), pool=spec.character_pool, index=s)
        kinds = [g.kind for g in recipe.garments if g.kind in DRAPED_KINDS]
        if not kinds:
            s += 1
            continue
        found += 1
        ph = recipe.phenotype
        kind = kinds[0]
        st = drape_settings(kind, "full")
        g = drape_garment(kind, ph, st)
        binds, bind_s = {}, {}
        for it in variants:
            t = time.perf_counter()
            binds[it] = bind_loose(g, ph, iterations=None if it < 0 else it)
            bind_s[it] = time.perf_counter() - t
        rest_pinch = hem_split(g.vertices, st.n_around)[0]
        print(f"\nsubject {s} ({kind}, {len(g.vertices)} cloth vertices, default diffusion "
              f"{loose_iterations(g)} steps; rest drape pinch {100 * rest_pinch:.1f} cm); "
              f"binding s: " + ", ".join(f"{it}: {bind_s[it]:.2f}" for it in variants) + f"  [load {load()}]")
        print(f"  {'pose':24s} {'steps':>5s} {'pinch cm':>8s} {'deficit':>7s} {'raw mm':>7s} {'worst mm':>8s} "
              f"{'p99 mm':>7s} {'inward':>6s} {'ms':>6s} {'sim mean/max cm':>16s}")
        for j, pose, label, spread, lift in stride_poses(args.seed, s, source.name, ph, args.poses):
            bones = dict(pose.bones)
            run = run_anny(ph, bones)
            normals = vertex_normals(run["vertices"], faces)
            sim = None
            if refs < args.reference:
                t = time.perf_counter()
                sim = simulate_into_pose([g], ph, bones, fabric=st)[0]
                sim_s = time.perf_counter() - t
                sim = push_out(sim, run["vertices"], normals, faces)
                refs += 1
            name = f"{source.name} {j} {label} ({spread:.0f}/{lift:.0f} deg)"
            for it in variants:
                t = time.perf_counter()
                raw = skin_points(binds[it], run["bone_poses"], run["rest_bone_poses"])
                v = push_out(raw, run["vertices"], normals, faces)
                ms = 1e3 * (time.perf_counter() - t)
                pinch, deficit = hem_split(v, st.n_around)
                depth_raw = float(penetration(run["vertices"], faces, raw).max())
                depth = penetration(run["vertices"], faces, v)
                inward = int((((v - raw) * vertex_normals(raw, g.faces)).sum(1) < -INWARD).sum())
                row = dict(subject=s, kind=kind, pose=name, steps=it, pinch=pinch, deficit=deficit, raw=depth_raw,
                           worst=float(depth.max()), p99=float(np.percentile(depth, 99)), ms=ms, inward=inward)
                ref = ""
                if sim is not None:
                    d = np.linalg.norm(v - sim, axis=1)
                    row.update(sim_mean=float(d.mean()), sim_max=float(d.max()))
                    ref = f"{100 * d.mean():6.1f} / {100 * d.max():5.1f}"
                rows.append(row)
                label = "auto" if it < 0 else str(it)
                print(f"  {name:24s} {label:>5s} {100 * pinch:8.1f} {100 * deficit:6.1f}% {1e3 * depth_raw:7.1f} "
                      f"{1e3 * row['worst']:8.2f} {1e3 * row['p99']:7.2f} {inward:6d} {ms:6.0f} {ref:>16s}", flush=True)
            if sim is not None:
                sp, sd = hem_split(sim, st.n_around)
                print(f"  {'':24s} {'sim':>5s} {100 * sp:8.1f} {100 * sd:6.1f}%   (newton VBD, {sim_s:.0f} s, "
                      f"load {load()})")
        s += 1
    for group, keep in (("strides (walk, random)", lambda x: " sit " not in x["pose"]),
                        ("seated (hem over the lap: deficit not meaningful)", lambda x: " sit " in x["pose"])):
        sel = [x for x in rows if keep(x)]
        if not sel:
            continue
        print(f"\n{group}: {len(sel) // len(variants)} (subject, pose) cases [load {load()}]")
        print(f"  {'steps':>5s} {'pinch cm max':>12s} {'median':>7s} {'deficit max':>11s} {'median':>7s} "
              f"{'worst mm':>8s} {'p99 mm max':>10s} {'inward sum':>10s} {'ms median':>9s} {'sim mean cm':>11s}")
        for it in variants:
            r = [x for x in sel if x["steps"] == it]
            sims = [x["sim_mean"] for x in r if "sim_mean" in x]
            label = "auto" if it < 0 else str(it)
            pinch = [x["pinch"] for x in r]
            print(f"  {label:>5s} {100 * max(pinch):12.1f} {100 * np.median(pinch):7.1f}"
                  f" {100 * max(x['deficit'] for x in r):10.1f}% {100 * np.median([x['deficit'] for x in r]):6.1f}%"
                  f" {1e3 * max(x['worst'] for x in r):8.2f} {1e3 * max(x['p99'] for x in r):10.2f}"
                  f" {sum(x['inward'] for x in r):10d} {np.median([x['ms'] for x in r]):9.0f} {(100 * np.mean(sims)) if sims else float('nan'):11.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
