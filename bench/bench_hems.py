"""Garment edges (necklines, hems, cuffs): how rough they are, before and after cutting along a level set.

    python bench/bench_hems.py [--before TREE]                       # roughness table
    python bench/bench_hems.py --picture docs/hems.png --before TREE [--size 512] [--spp 24]

In: every shell garment kind (`garments.SHELL_KINDS`) built alone on the phenotypes of benchmark seeds 2, 4, 6.
Out: per kind and phenotype, the open edges of the garment's rest-pose surface (`geometry.boundary_loops`, vertices
at body vertex + offset along the normal, or their blends) and each loop's roughness (`geometry.edge_roughness`: how
much the curvature of the loop, resampled every 5 mm, varies beyond that of a circle of the same length; 1/m, 0 for
a circle).

`--before TREE`: also measure (and, with --picture, render) the garments made by another checkout of this repository
(e.g. a `git worktree` of the commit before the level-set cut): this script re-runs itself there (cwd and
PYTHONPATH = TREE) with `--dump`, which writes the meshes (or the rendered crops) to an .npz using only the package
API both versions share; the measuring is always done by this tree's code, so both columns use one metric.
`--picture`: a subject in a t-shirt and shorts (benchmark seed 2's body), three 512x512 crops - neckline, sleeve cuff,
shorts' hem - top row TREE's code, bottom row this tree's; rendered by `render_frame` under Blender's studio HDRI.
Prints `uptime` (the machine's load) first.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

KINDS = ("tshirt", "longsleeve", "jacket", "trousers", "shorts")
SEEDS = (2, 4, 6)
# The galleries' light, as subjects_gallery.studio_environment builds it; not imported from there, because that
# module puts this checkout first on sys.path, and the --dump run of another TREE must import TREE's code.
STUDIO_HDRI = Path("/usr/share/blender/datafiles/studiolights/world/studio.exr")


def _rest_surface(part, feats) -> np.ndarray:
    """Rest-pose positions of a garment's vertices, for either anchoring (one body vertex, or a blend)."""
    v, n = feats.rest_vertices, feats.rest_normals
    if part.blend_vertices is None:
        return v[part.body_vertex] + part.offset[:, None] * n[part.body_vertex]
    w = part.blend_weights.astype(np.float64)[..., None]
    nb = (n[part.blend_vertices] * w).sum(1)
    nb /= np.linalg.norm(nb, axis=1, keepdims=True)
    return (v[part.blend_vertices] * w).sum(1) + part.offset[:, None] * nb


def dump_meshes() -> dict[str, np.ndarray]:
    from rh_dataset.characters import recipe_from_seed
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.garments import build_garments
    from rh_dataset.characters.recipe import Garment

    out = {}
    for seed in SEEDS:
        feats = body_features(recipe_from_seed(seed, "benchmark", 0).phenotype)
        for kind in KINDS:
            part = build_garments((Garment(kind, (0.5, 0.5, 0.5)),), feats)[0]
            out[f"{kind}/{seed}/v"] = _rest_surface(part, feats)
            out[f"{kind}/{seed}/f"] = np.asarray(part.faces)
    return out


def _subject():
    from rh_dataset.characters import recipe_from_seed
    from rh_dataset.characters.recipe import Garment

    r = recipe_from_seed(2, "benchmark", 0)
    garments = (Garment("shorts", (0.16, 0.22, 0.42)), Garment("tshirt", (0.85, 0.78, 0.62)))
    return dataclasses.replace(r, garments=garments, headwear=())


def _crop_cameras(character, posed, size: int):
    """Neckline (front), left sleeve cuff (front-left), left shorts hem (front-left): targets from the posed body
    (bone groups and the limb coordinates), identical for both trees (the body does not change)."""
    from rh_common.camera import Camera
    from rh_dataset.characters.body_features import GROUPS, body_features

    feats = body_features(character.phenotype)
    pos = np.zeros((len(feats.rest_vertices), 3))
    pos[character.part("body").body_vertex] = next(m for m in posed if m.name == "body").vertices
    left = feats.rest_vertices[:, 0] > 0
    neck = pos[feats.group == GROUPS.index("neck")].mean(0) - [0.0, 0.0, 0.05]
    cuff = pos[left & (np.abs(np.nan_to_num(feats.arm_t, nan=9.0) - 0.3) < 0.03)].mean(0)
    hem = pos[left & (np.abs(np.nan_to_num(feats.leg_t, nan=9.0) - 0.42) < 0.03)].mean(0)
    cams = []
    for target, direction, dist in ((neck, (0.0, -1.0, 0.25), 0.55), (cuff, (0.5, -1.0, 0.1), 0.5),
                                    (hem, (0.4, -1.0, 0.1), 0.55)):
        d = np.asarray(direction) / np.linalg.norm(direction)
        cams.append(Camera(size, size, 30.0, tuple(map(float, target + dist * d)), tuple(map(float, target))))
    return cams


def dump_tiles(size: int, spp: int) -> dict[str, np.ndarray]:
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import load_mitsuba, select_variant

    select_variant(None)
    mi = load_mitsuba()
    env = {"type": "envmap", "filename": str(STUDIO_HDRI),
           "to_world": mi.ScalarTransform4f().rotate([0, 0, 1], 200).rotate([1, 0, 0], 90)}
    character = build_character(_subject(), 512)
    posed = pose_character(character)
    out = {}
    for i, cam in enumerate(_crop_cameras(character, posed, size)):
        t = time.perf_counter()
        r = render_frame(posed, env, cam, RenderSettings(spp=spp, aov_spp=4, max_depth=8), ["image"], seed=i)
        out[f"tile{i}"] = quantize8(srgb_encode(np.clip(r.layers["image"] * 1.3, 0.0, None)))
        print(f"  crop {i}: {time.perf_counter() - t:.1f} s", flush=True)
    return out


def _from_tree(tree: Path, args: list[str]) -> dict[str, np.ndarray]:
    """Run this script's --dump in another checkout (its code on the path) and read what it wrote."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "dump.npz"
        env = dict(os.environ, PYTHONPATH=str(tree))
        subprocess.run([sys.executable, str(Path(__file__).resolve()), "--dump", str(path), *args], cwd=tree,
                       env=env, check=True)
        with np.load(path) as z:
            return {k: z[k] for k in z.files}


def measure(meshes: dict[str, np.ndarray]) -> dict[tuple[str, int], list[tuple[float, float]]]:
    """{(kind, seed): [(loop length m, roughness 1/m), ...]} longest loop first."""
    from rh_dataset.characters.geometry import boundary_loops, edge_roughness

    out = {}
    for kind in KINDS:
        for seed in SEEDS:
            loops = boundary_loops(meshes[f"{kind}/{seed}/v"], meshes[f"{kind}/{seed}/f"])
            rows = []
            for lp in loops:
                length = float(np.linalg.norm(lp - np.roll(lp, -1, 0), axis=1).sum())
                rows.append((length, edge_roughness(lp)))
            out[kind, seed] = sorted(rows, reverse=True)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", type=Path, help="another checkout whose garments to compare with")
    p.add_argument("--picture", type=Path, help="write the before/after crops here (needs --before)")
    p.add_argument("--size", type=int, default=512, help="width and height in pixels of each --picture crop "
                   "(default 512)")
    p.add_argument("--spp", type=int, default=24, help="samples per pixel of the --picture crops (default 24)")
    p.add_argument("--dump", type=Path, help=argparse.SUPPRESS)
    p.add_argument("--tiles", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.dump is not None:
        data = dump_tiles(args.size, args.spp) if args.tiles else dump_meshes()
        np.savez(args.dump, **data)
        return
    print("load:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(), flush=True)
    if args.picture is not None:
        if args.before is None:
            raise SystemExit("bench_hems: --picture needs --before TREE (the checkout to compare with)")
        from rh_common.imageio import write_png

        t = time.perf_counter()
        before = _from_tree(args.before, ["--tiles", "--size", str(args.size), "--spp", str(args.spp)])
        after = dump_tiles(args.size, args.spp)
        rows = [np.concatenate([d[f"tile{i}"] for i in range(3)], 1) for d in (before, after)]
        write_png(args.picture, np.concatenate(rows, 0))
        print(f"wrote {args.picture} ({time.perf_counter() - t:.0f} s)")
        return
    t = time.perf_counter()
    after = measure(dump_meshes())
    before = measure(_from_tree(args.before, [])) if args.before is not None else None
    print(f"measured in {time.perf_counter() - t:.1f} s")
    print("edge roughness (geometry.edge_roughness: curvature spread beyond a circle of the same length, 5 mm steps, "
          "1/m), longest loop first; "
          "loop lengths in cm")
    for kind in KINDS:
        for seed in SEEDS:
            fmt = lambda rows: " ".join(f"{100 * ln:5.1f}cm:{r:6.1f}" for ln, r in rows)  # noqa: E731
            line = f"{kind:10s} seed {seed}  after {fmt(after[kind, seed])}"
            if before is not None:
                line += f"   | before {fmt(before[kind, seed])}"
            print(line)
    for name, res in (("after", after), ("before", before)):
        if res is None:
            continue
        for kind in KINDS:
            r = [x for seed in SEEDS for _, x in res[kind, seed]]
            print(f"{name:6s} {kind:10s} loops {len(r):2d}  roughness median {np.median(r):6.1f}  max {max(r):6.1f}")


if __name__ == "__main__":
    main()
