"""Draped skirt (newton's VBD cloth solver, rh_dataset/characters/drape.py), or another draped kind (`--kind`):
drape time, per-frame cost of the skinned path, and how far the cloth sinks into the body over sampled poses;
optionally a draft render.

    python bench/bench_cloth.py                                   # drape + 8 poses (~2-3 min on a busy 2-core box)
    python bench/bench_cloth.py --kind draped_trousers            # the wide trousers (~8 min: two full drapes)
    python bench/bench_cloth.py --kind draped_shorts              # the loose shorts (~3 min)
    python bench/bench_cloth.py --kind draped_straight_trousers   # the straight-leg trousers
    python bench/bench_cloth.py --kind draped_coat                # the open coat, and how deep it sinks into the
                                                                  # layers under it and its shell into it
    python bench/bench_cloth.py --kind draped_jacket              # the open jacket, the same measures
    python bench/bench_cloth.py --image docs/draped_skirt.png   # also 256 px drafts: rest front | side | a walk

Figures: drape wall seconds (uncached, Warp kernels already compiled; the first run ever adds their compilation,
printed separately as `first drape`), the cached load, the skinning per frame against the shell's posing (the
skirt's, or the trousers' for draped trousers, the shorts' for draped shorts)
(both after one anny run, which every frame pays anyway), and penetration = trimesh signed distance of the skinned
cloth vertices into the posed body (metres, > 0 inside): the worst over all vertices, its 99th percentile, and the
share of vertices inside, per pose label; and how many of the drape's edges pass through the cloth itself
(`cloth_pose.self_crossings`), with and without the drape's self-contact. The load average is printed with the times.
A kind worn over draped cloth (`drape.DRAPED_OVER`: a loose top over a draped skirt or wide trousers, an open jacket
or coat over a loose top) is draped over it, as the generator drapes it (that cloth's drape is not timed).
The skinned cloth is pushed out to its kind's clearance (`drape.push_clearance`: the coat's is larger). For the coat
and the open jacket (the outermost layer, panels under the shell "coat"), per pose also: the character's posed
garments (`pose_character`, skinned), the worst depth of
a panel vertex under any garment under it (`cloth_pose.layer_depth`, vertices within 2 cm of that garment; sleeves
apart, where a forearm on the lap presses through the panel), and how
many vertices of its shell below the panels' pinned ring lie outside the panels (the shell poking through them).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def benchmark_recipe(index: int, seed: int = 0, pool: bool = False):
    """Benchmark subject `index` as rh-generate draws it at dataset seed `seed` (`sample_recipe(rng_for(seed,
    "character", index))`), or with `pool` the benchmark pool's recipe `index` (`recipe_from_seed(derive_seed(
    "benchmark", index, seed))`, as `draped_recipe` walks them: combinations a seed's 49 subjects do not draw)."""
    from rh_dataset.characters.recipe_draws import derive_seed, recipe_from_seed, sample_recipe
    from rh_dataset.generate.seeding import rng_for

    if pool:
        return recipe_from_seed(derive_seed("benchmark", index, seed), "benchmark", index)
    return sample_recipe(rng_for(seed, "character", index), pool="benchmark", index=index)


def draped_recipe(index: int, seed: int = 0, kind: str = "draped_skirt"):
    """The first benchmark recipe from `index` on (dataset seed `seed`) that draws `kind` (the draped skirt: every
    skirt recipe_from_seed draws is)."""
    from rh_dataset.characters.recipe_draws import derive_seed, recipe_from_seed

    i = index
    while True:
        r = recipe_from_seed(derive_seed("benchmark", i, seed), "benchmark", i)
        if r.garment(kind) is not None:
            return r
        i += 1


def coat_overlap(ch, z_ring: float) -> np.ndarray:
    """(V,) bool over the vertices of a character's coat shell: its trunk (not sleeves) under the panels' pinned
    ring `z_ring` in the rest pose, but for the front opening's 4 cm either side of the middle."""
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.body_features import body_features

    part = ch.part("coat")
    rest = {m.name: m for m in pose_character(ch, {})}["coat"].vertices
    torso = body_features(ch.phenotype).in_groups("torso")[part.body_vertex]
    return torso & (rest[:, 2] < z_ring) & ((np.abs(rest[:, 0]) > 0.04) | (rest[:, 1] > 0.0))


def coat_layers(recipe, poses, g, level: str = "full", kind: str = "draped_coat"
                ) -> tuple[float, int]:
    """The coat (or the open jacket: `kind`) against the layers under it and its own shell, in the rest pose and each
    pose (module docstring); `g`: its drape at `level`. Returns (worst panel depth under a layer below (m), shell
    vertices through the panels over all poses)."""
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.cloth_pose import layer_depth

    ch = build_character(recipe, 64, drape=level)
    inner = [gm.kind for gm in recipe.garments if gm.kind != kind]
    z_ring = float(g.vertices[g.pinned, 2].mean())
    # The shell's trunk vertices under the ring in the rest pose (its overlap; not the sleeves, and not within 4 cm
    # of the front's middle, where the panels are open and the closest panel point is an edge), followed into each
    # pose by index.
    low = coat_overlap(ch, z_ring)
    # The layers' faces off the arms, and on them (sleeves): a forearm laid on the lap presses its sleeve through
    # the panel over the thigh (the skinned cloth cannot give way to it), which is an arm-against-coat contact.
    arm = body_features(ch.phenotype).in_groups("upperarm", "lowerarm", "hand")
    on_arm = {k: arm[ch.part(k).body_vertex][ch.part(k).faces].all(1) for k in inner}
    worst, poked = -np.inf, 0
    for label, bones in [("rest", {})] + [(p.label, dict(p.bones)) for p in poses]:
        posed = {m.name: m for m in pose_character(ch, bones)}
        panel = posed[kind].vertices.astype(np.float64)
        under, count = {}, {}
        for k in inner:
            for name, sel in ((k, ~on_arm[k]), (f"{k} sleeves", on_arm[k])):
                if sel.any():
                    d = layer_depth(panel, posed[k].vertices, posed[k].faces[sel])
                    under[name] = float(np.nanmax(d)) if np.isfinite(d).any() else -np.inf
                    count[name] = int((np.nan_to_num(d, nan=-1.0) > 0.001).sum())
        d = layer_depth(posed["coat"].vertices[low].astype(np.float64), panel, posed[kind].faces)
        out = int((d < 0).sum())
        worst = max(worst, max(v for k, v in under.items() if not k.endswith("sleeves")))
        poked += out
        print(f"  {label:12s} panel depth under the layers below (mm, worst; vertices > 1 mm): "
              + ", ".join(f"{k} {1e3 * v:.2f} ({count[k]})" for k, v in under.items() if np.isfinite(v))
              + f";  coat shell vertices under the ring outside the panels: {out} of {int(low.sum())} "
                f"(worst {1e3 * max(0.0, -float(np.nanmin(d, initial=0.0))):.2f} mm)")
    print(f"coat: worst panel depth under a layer below (sleeves aside) over rest + {len(poses)} poses "
          f"{1e3 * worst:.2f} mm; shell "
          f"vertices poking through the panels, all poses: {poked}")
    return worst, poked


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--index", type=int, default=0, help="first benchmark index searched for a skirt wearer")
    ap.add_argument("--poses", type=int, default=8, help="sampled poses the penetration is measured over")
    ap.add_argument("--image", type=Path, default=None, help="write a 256 px draft render of the character here")
    ap.add_argument("--kind", default="draped_skirt", help="draped garment kind (drape.DRAPED_KINDS)")
    args = ap.parse_args(argv)

    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.characters.drape import (DRAPED_KINDS, SHELL_KINDS_OVER, bind_loose, drape_garment,
                                             drape_settings, draped_over, penetration, piece_settings,
                                             push_clearance, push_out, skin_points)
    from rh_dataset.poses import sample_poses

    kind = args.kind
    recipe = draped_recipe(args.index, kind=kind)
    ph = recipe.phenotype
    st = drape_settings(kind)
    load = lambda: " ".join(open("/proc/loadavg").read().split()[:3])  # noqa: E731
    print(f"character: benchmark index {recipe.index}, garments {[g.kind for g in recipe.garments]}")
    t = time.perf_counter()
    drape_garment(kind, ph, dataclasses.replace(st, steps=1), use_cache=False)
    print(f"first drape (1 step; Warp kernel compile on a cold cache): {time.perf_counter() - t:.1f} s")
    import tempfile

    # The draped cloth the kind is worn over and draped over (drape.DRAPED_OVER: a loose top over a draped skirt, an
    # open jacket over a loose top), draped first as build_garments drapes it, from the default cache (not timed).
    under = {}
    for k in (g.kind for g in recipe.garments):
        if k == kind:
            break
        if k in DRAPED_KINDS:
            under[k] = drape_garment(k, ph, piece_settings(k, "full", [g.kind for g in recipe.garments]),
                                     over=draped_over(k, under))
    over = draped_over(kind, under)
    if over:
        print(f"draped over: {[c.kind for c in over]}")
    os.environ["RH_DRAPE_CACHE"] = tempfile.mkdtemp(prefix="bench_cloth_")  # a cold cache: the drape is timed
    t = time.perf_counter()
    g = drape_garment(kind, ph, st, over=over)
    t_drape = time.perf_counter() - t
    n = len(g.vertices)
    print(f"drape: {n} particles, {len(g.faces)} triangles, {st.steps} steps of {st.dt} s, {st.iterations} VBD "
          f"iterations: {t_drape:.1f} s  (load {load()})")
    t = time.perf_counter()
    drape_garment(kind, ph, st, over=over)
    print(f"cached drape load: {1e3 * (time.perf_counter() - t):.1f} ms")
    from rh_dataset.characters.cloth_pose import self_crossings

    plain = drape_garment(kind, ph, dataclasses.replace(st, self_contact=False), use_cache=False, over=over)
    print(f"rest drape: {self_crossings(g.vertices, g.faces)} of its edges cross the cloth; draped without "
          f"self-contact: {self_crossings(plain.vertices, plain.faces)}")
    t = time.perf_counter()
    b = bind_loose(g, ph)
    print(f"skinning transfer (once per character): {time.perf_counter() - t:.2f} s")

    faces = body_topology().faces
    rest = run_anny(ph)
    pen0 = penetration(rest["vertices"], faces, g.vertices)
    print(f"rest pose: worst penetration {1e3 * pen0.max():.2f} mm, inside {100 * (pen0 > 0).mean():.2f} %")
    worst = -np.inf
    skin_t, shell_t = [], []
    from rh_dataset.characters.garments import build_garments
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.characters.recipe import Garment

    shell_kind = {"draped_trousers": "trousers", "draped_straight_trousers": "trousers", "draped_shorts": "shorts",
                  "draped_coat": "jacket",
                  "draped_jacket": "jacket", "draped_tshirt": "tshirt",
                  "draped_longsleeve": "longsleeve"}.get(kind, "skirt")
    shell = build_garments((Garment(shell_kind, (0.5, 0.5, 0.5)),), body_features(ph))[0]
    from rh_dataset.mesh import vertex_normals

    raw_worst = -np.inf
    poses = sample_poses(np.random.default_rng(7), load_anny(), args.poses)
    for pose in poses:
        run = run_anny(ph, dict(pose.bones))
        nrm = vertex_normals(run["vertices"], faces)  # every frame computes these for the body anyway
        t = time.perf_counter()
        raw = skin_points(b, run["bone_poses"], run["rest_bone_poses"])
        pts = push_out(raw, run["vertices"], nrm, faces, push_clearance(kind))
        skin_t.append(time.perf_counter() - t)
        t = time.perf_counter()
        w = shell.blend_weights.astype(np.float64)[..., None]
        p = (run["vertices"][shell.blend_vertices] * w).sum(1)
        nb = (nrm[shell.blend_vertices] * w).sum(1)
        _ = p + shell.offset[:, None] * nb / np.linalg.norm(nb, axis=1, keepdims=True)
        shell_t.append(time.perf_counter() - t)
        pen_raw = penetration(run["vertices"], faces, raw)
        pen = penetration(run["vertices"], faces, pts)
        raw_worst = max(raw_worst, float(pen_raw.max()))
        worst = max(worst, float(pen.max()))
        print(f"  pose {pose.label:12s} skinned only: worst {1e3 * pen_raw.max():6.2f} mm inside "
              f"{100 * (pen_raw > 0).mean():5.2f} %;  + push_out: worst {1e3 * pen.max():6.2f} mm  p99 "
              f"{1e3 * np.percentile(pen, 99):6.2f} mm  inside {100 * (pen > 0).mean():5.2f} %")
    print(f"worst vertex penetration over {args.poses} poses: skinned only {1e3 * raw_worst:.2f} mm, "
          f"with push_out {1e3 * worst:.2f} mm")
    print(f"per frame: skinned drape + push_out {1e3 * np.median(skin_t):.2f} ms, shell {shell_kind} anchors "
          f"{1e3 * np.median(shell_t):.2f} ms (medians, body normals excluded from both; load {load()})")
    if SHELL_KINDS_OVER.get(kind) == "coat":  # the coat, the open jacket: panels under the shell "coat"
        coat_layers(recipe, poses, g, kind=kind)

    if args.image is not None:
        from rh_common.colourspace import quantize8, srgb_encode
        from rh_common.imageio import write_png
        from rh_dataset.characters.preview import render_preview

        character = build_character(recipe, 512)
        shown = next((p for p in poses if p.label == "walk"), poses[0]) if poses else None
        tiles = []
        from rh_dataset.poses.pose import rotation_about_z

        views = [({}, None), ({}, rotation_about_z(90.0))]  # rest pose from the front and from its left
        if shown is not None:
            views.append((dict(shown.bones), None))
        for bones, turn in views:
            posed = pose_character(character, bones, turn)
            img = render_preview(posed, width=256, height=256, spp=32, denoise=True)
            tiles.append(quantize8(srgb_encode(np.clip(img, 0, None) * 1.3)))
        write_png(args.image, np.concatenate(tiles, axis=1))  # rest front | rest side | a sampled walk
        print(f"wrote {args.image}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
