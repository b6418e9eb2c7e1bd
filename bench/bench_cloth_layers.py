"""Draped cloth over draped cloth (drape.DRAPED_OVER: a loose t-shirt or long sleeve over a draped skirt or wide
trousers; an open jacket or coat over a loose top, and the jacket over the skirt under that top; the hoodie's hood
over its body): how far the outer layer lies under the cloth under it, at rest and posed, and what keeping it out
costs.

    python bench/bench_cloth_layers.py                       # benchmark subjects 5 and 39 (seed 0), 3 test poses
    python bench/bench_cloth_layers.py --subjects 20,24 --poses 2 --drape coarse
    python bench/bench_cloth_layers.py --subjects 14,41,45   # open jackets and a coat over loose tops
    python bench/bench_cloth_layers.py --subjects 2,26       # open jackets over loose tops over draped skirts
    python bench/bench_cloth_layers.py --subjects 13,28,38,42 --through   # the hoods over the hoodies' bodies
    python bench/bench_cloth_layers.py --subjects 13,28,42 --top draped_hoodie_body --through   # and those over bottoms
    python bench/bench_cloth_layers.py --seed 2 --subjects 0 # a loose top over wide trousers (none at seed 0)
    python bench/bench_cloth_layers.py --pool --subjects 4,17,52 --poses 4 --modes skinned --two-passes
                                                             # tops and jackets over the lifted wide trousers
    python bench/bench_cloth_layers.py --subjects 26 --poses 2 --modes skinned --through   # cloth out through the top
    python bench/bench_cloth_layers.py --pool --subjects 4 --poses 4 --modes skinned --through --no-tuck

Subjects are the generator's own (rh-generate's `sample_recipe(rng_for(seed, "character", s))`, benchmark pool), so
the numbers are those of the dataset's frames (with `--pool`, the benchmark pool's recipes by index instead,
`recipe_from_seed(derive_seed("benchmark", i, seed))`, as bench_cloth.draped_recipe draws them); each must wear
draped cloth over draped cloth (the outermost such layer over draped cloth: the top over a skirt, or the jacket or
coat over the top, and over a skirt under it; the cloth under it is draped as the generator drapes it, each over
what it is worn over). Below, "the top" is that outer layer (or `--top`), measured against each draped cloth it is
draped over.
Per subject:
  drape     the top draped on the body alone (as before 3 December) and over the cloth under it (`over`, its
            collider and pattern): the seconds of each drape (a cold cache: the drape is timed) and the top's
            vertices under the cloth's surface at rest (`cloth_pose.layer_depth`, within 3 cm, not beyond its open
            edges): how many lie deeper than 1 mm and the worst depth;
  posed     for the rest pose and each test pose (`sample_pose(rng_for(seed, "pose", s, "test", j))`), both cloth
            modes of `pose_character` ("skinned", "simulated"), the same layer measure on the posed top, without
            `cloth_pose.push_over_layers` (the final push over the cloth under it, replaced by the identity) and with
            it, and the push's own seconds. With `--two-passes`, also the layer measure after two passes of
            `push_over_layers` alone (`cycles=2, max_cycles=2`, its behaviour before LAYER_CYCLES_MAX) and whether
            the posed top is the same bits both ways. `--no-lift`: posed without `cloth_pose.lift_over_skin`;
            `--max-passes N`: posed (and pushed, `push s`) with at most N passes instead of LAYER_CYCLES_MAX.
  through   with `--through`, the other way round, after the push: of each draped cloth under the top, how many
            vertices lie over the top's surface (`layer_depth` < 0, within 3 cm, not beyond the top's open edges),
            the farthest (mm), and of those, how many a camera sees (8 horizontal views around the subject, the ray
            from 2 mm off the vertex along its normal meeting no posed mesh; bench_cloth_pose.seen_around): the
            inner cloth come out through the top between the top's vertices, which the push, moving only the top's
            vertices, cannot see. Posing puts it back under (character._tuck_inner_layers); `--no-tuck` poses
            without that. Not measured for the hoodie's hood (character.TUCK_UNDER_NOT): a bag laid back, its
            sheet on the back faces the body's cloth, which would count as over it.
--figure PATH: the first subject in its test pose --figure-pose (default the first), skinned, rendered without the
tuck (top row) and with it (bottom), front and right, the lap framed at 512 px (standard preset, 64 spp).
The load average is printed with the times: the machine is shared.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


def under(points: np.ndarray, cloth_v: np.ndarray, cloth_f: np.ndarray) -> tuple[int, float]:
    """(vertices deeper than 1 mm under the cloth, the worst depth in mm; -inf when none is within reach)."""
    from rh_dataset.characters.cloth_pose import LAYER_REACH, layer_depth

    d = layer_depth(np.asarray(points, np.float64), np.asarray(cloth_v, np.float64), cloth_f, LAYER_REACH)
    worst = float(np.nanmax(d)) if np.isfinite(d).any() else -np.inf
    return int((np.nan_to_num(d, nan=-1.0) > 0.001).sum()), 1e3 * worst


def over_top(inner, top, meshes) -> tuple[int, float, int]:
    """Of the posed mesh `inner`'s vertices: (those lying over the posed mesh `top`'s surface within reach, the
    farthest in mm (0.0 when none), and of those, how many a camera around the subject sees: 8 horizontal views, the
    ray from 2 mm off the vertex along its normal meeting none of the posed `meshes`; bench_cloth_pose.seen_around)."""
    from bench_cloth_pose import seen_around
    from rh_dataset.characters.cloth_pose import LAYER_REACH, layer_depth

    points = np.asarray(inner.vertices, np.float64)
    d = layer_depth(points, np.asarray(top.vertices, np.float64), top.faces, LAYER_REACH)
    out = np.nan_to_num(d, nan=1.0) < 0.0
    seen = int(seen_around(points[out], np.asarray(inner.normals, np.float64)[out], meshes).sum())
    return int(out.sum()), (-1e3 * float(d[out].min()) if out.any() else 0.0), seen


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", default="5,39",
                    help="comma-separated benchmark subjects (rh-generate's, at --seed) wearing a loose top over "
                         "draped cloth")
    ap.add_argument("--poses", type=int, default=3, help="test poses of the pose prior per subject")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the recipes and poses come from")
    ap.add_argument("--drape", default="full", choices=("full", "coarse"), help="drape level (RenderSettings.drape)")
    ap.add_argument("--pool", action="store_true",
                    help="--subjects are benchmark pool recipe indices (bench_cloth.draped_recipe's), "
                         "not rh-generate's")
    ap.add_argument("--modes", nargs="+", default=["skinned", "simulated"], choices=("skinned", "simulated"),
                    help="cloth modes of pose_character to measure")
    ap.add_argument("--no-lift", action="store_true",
                    help="pose without cloth_pose.lift_over_skin (the dress's and wide trousers' lift over skin)")
    ap.add_argument("--through", action="store_true",
                    help="also count the inner cloths' vertices that lie over the posed top (come out through it)")
    ap.add_argument("--no-tuck", action="store_true",
                    help="pose without character._tuck_inner_layers (the cloth under the top put back under it "
                         "where it came out through it)")
    ap.add_argument("--figure", type=Path, default=None,
                    help="write the first subject in test pose --figure-pose, without and with the tuck, here (PNG)")
    ap.add_argument("--figure-pose", type=int, default=0, help="the test pose of --figure")
    ap.add_argument("--max-passes", type=int, default=None,
                    help="push_over_layers' max_cycles for the posed runs (default: LAYER_CYCLES_MAX)")
    ap.add_argument("--top", default=None,
                    help="the draped piece measured over the cloth under it (default: the outermost such piece; "
                         "draped_hoodie_body: the hoodie's body over the bottom, under its hood)")
    ap.add_argument("--two-passes", action="store_true",
                    help="also push over the layers with two passes only (before LAYER_CYCLES_MAX) and compare")
    args = ap.parse_args(argv)

    import rh_dataset.characters.character as character_module
    from rh_dataset.characters.character import TUCK_UNDER_NOT
    from rh_common.body_model import load_anny
    from bench_cloth import benchmark_recipe
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.characters.cloth_pose import push_over_layers
    from rh_dataset.characters.drape import (DRAPED_OVER, drape_garment, drape_layers, draped_over, draped_pieces,
                                             piece_settings)
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose

    tuck = character_module._tuck_inner_layers
    if args.no_tuck:  # every pose below
        character_module._tuck_inner_layers = tuck = lambda *a: None  # noqa: E731
    if args.max_passes is not None:  # every push below, pose_character's included
        def push_over_layers(v, layers, gap, _push=push_over_layers, _most=args.max_passes, **kw):
            return _push(v, layers, gap, **{"max_cycles": _most, **kw})
        character_module.push_over_layers = push_over_layers
    os.environ["RH_DRAPE_CACHE"] = tempfile.mkdtemp(prefix="bench_cloth_layers_")  # cold: the drapes are timed
    figured = False
    print(f"load average at start: {load()}; drape level {args.drape}")
    for s in (int(x) for x in args.subjects.split(",")):
        recipe = benchmark_recipe(s, args.seed, args.pool)
        kinds = [g.kind for g in recipe.garments]
        pieces = [p for k in kinds for p in draped_pieces(k)]  # the hoodie: its body, then its hood
        top = next((k for k in reversed(pieces) if k in DRAPED_OVER and set(DRAPED_OVER[k]) & set(pieces)
                    and args.top in (None, k)), None)
        if top is None:
            ap.error(f"benchmark {'pool recipe' if args.pool else 'subject'} {s} wears no draped cloth "
                     f"{args.top or ''} over draped cloth: {kinds}")
        inners = [k for k in pieces if k in DRAPED_OVER[top]]  # innermost first
        ph = recipe.phenotype
        print(f"\n{'pool recipe' if args.pool else 'subject'} {s}: {kinds}")
        # The cloth under the top, as build_garments drapes it (each piece over what it is worn over).
        draped = drape_layers(pieces[:pieces.index(top)], ph, args.drape, worn=kinds)
        clothes = draped_over(top, draped)

        def unders(points, layers) -> str:
            return ", ".join("{} {:d} ({:.1f})".format(k, *under(points, v, f)) for k, (v, f) in layers.items())

        for over in ((), clothes):
            t = time.perf_counter()
            g = drape_garment(top, ph, piece_settings(top, args.drape, kinds), over=over)
            secs = time.perf_counter() - t
            print(f"  drape of the {top} {'over the ' + ', '.join(inners) if over else 'on the body alone'}: "
                  f"{secs:.1f} s; at rest, vertices > 1 mm under (worst mm): "
                  f"{unders(g.vertices, {c.kind: (c.vertices, c.faces) for c in clothes})}  (load {load()})")
        character = build_character(recipe, 512, drape=args.drape)
        if args.no_lift:
            character = dataclasses.replace(character, parts=[
                dataclasses.replace(p, inside_skin=None, inside_depth=None) for p in character.parts])
        poses = [("rest", {})] + [(f"test {j} ({p.label})", dict(p.bones)) for j, p in enumerate(
            sample_pose(rng_for(args.seed, "pose", s, "test", j), load_anny()) for j in range(args.poses))]
        print(f"  {'pose':22s} {'mode':9s}  vertices > 1 mm under (worst mm): without push_over | with push_over | "
              f"push s" + (" | two passes only, same bits?" if args.two_passes else ""))
        for label, bones in poses:
            for mode in args.modes:
                character_module.push_over_layers = lambda v, *a, **k: np.asarray(v, np.float64)  # noqa: E731
                character_module._tuck_inner_layers = lambda *a: None  # noqa: E731
                try:
                    raw = {m.name: m for m in pose_character(character, bones, None, mode)}
                finally:
                    character_module.push_over_layers = push_over_layers
                    character_module._tuck_inner_layers = tuck
                t = time.perf_counter()
                posed = {m.name: m for m in pose_character(character, bones, None, mode)}
                t_all = time.perf_counter() - t
                t = time.perf_counter()
                push_over_layers(raw[top].vertices, [(raw[k].vertices, raw[k].faces) for k in inners], 0.004)
                t_push = time.perf_counter() - t
                before = unders(raw[top].vertices, {k: (raw[k].vertices, raw[k].faces) for k in inners})
                after = unders(posed[top].vertices, {k: (posed[k].vertices, posed[k].faces) for k in inners})
                two = ""
                if args.two_passes:
                    character_module.push_over_layers = lambda v, layers, gap: push_over_layers(  # noqa: E731
                        v, layers, gap, cycles=2, max_cycles=2)
                    try:
                        old = {m.name: m for m in pose_character(character, bones, None, mode)}
                    finally:
                        character_module.push_over_layers = push_over_layers
                    two = (f" | {unders(old[top].vertices, {k: (old[k].vertices, old[k].faces) for k in inners})}, "
                           f"{'same' if np.array_equal(old[top].vertices, posed[top].vertices) else 'differs'}")
                if args.through and top in TUCK_UNDER_NOT:
                    two += " | through: not measured (a bag laid back, character.TUCK_UNDER_NOT)"
                elif args.through:
                    two += " | through (seen): " + ", ".join("{} {:d} ({:.1f} mm; {:d})".format(k, *over_top(
                        posed[k], posed[top], list(posed.values()))) for k in inners)
                print(f"  {label:22s} {mode:9s}  {before} | {after} | {t_push:5.2f}{two} "
                      f"(posing {t_all:.1f} s; load {load()})", flush=True)
        if args.figure and not figured:
            bones = dict(sample_pose(rng_for(args.seed, "pose", s, "test", args.figure_pose), load_anny()).bones)
            figure(args.figure, character, bones, s, tuck)
            figured = True
    return 0


def figure(out: Path, character, bones: dict, s: int, tuck) -> None:
    """`--figure`: `character` posed by `bones` (skinned), rendered with rh-generate's standard preset for the test
    split at 64 spp under Blender's studio light, the posed body between 30 % and 75 % of its height (the lap)
    framed at 512 px, from the front and from its right: without the tuck (`character._tuck_inner_layers`, top row)
    and with it (bottom)."""
    import rh_dataset.characters.character as character_module
    from rh_common.camera import frame_body
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import body_bounds, pose_character
    from rh_dataset.cli import render_settings
    from rh_dataset.render.passes import render_frame
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import load_mitsuba, select_variant
    from subjects_gallery import studio_environment

    select_variant(None)
    env = studio_environment(load_mitsuba())
    test = next(x for x in load_protocol("protocol_a").splits if x.name == "test")
    settings = render_settings("standard", spp=64, aov_spp=4).for_split(test)
    rows = []
    for t in (lambda *a: None, tuck):
        character_module._tuck_inner_layers = t
        try:
            posed = pose_character(character, bones, None, "skinned")
        finally:
            character_module._tuck_inner_layers = tuck
        lo, hi = body_bounds(posed)
        a, b = lo.copy(), hi.copy()  # the lap: from 30 % to 75 % of the posed height
        a[2], b[2] = lo[2] + 0.3 * (hi[2] - lo[2]), lo[2] + 0.75 * (hi[2] - lo[2])
        cam = frame_body(a, b, 512, 512, 30.0, fill=0.9)
        centre, reach = np.array(cam.target), np.linalg.norm(np.array(cam.origin) - np.array(cam.target))
        views = []
        for deg in (0.0, 270.0):  # the front (-Y), then the subject's right
            r = np.radians(deg)
            origin = tuple(float(x) for x in centre + reach * np.array([-np.sin(r), -np.cos(r), 0.0]))
            img = render_frame(posed, env, dataclasses.replace(cam, origin=origin), settings, ["image"],
                               seed=s).layers["image"]
            views.append(quantize8(srgb_encode(np.clip(img * 1.3, 0.0, None))))
        rows.append(np.concatenate(views, 1))
    write_png(out, np.concatenate(rows, 0))
    print(f"wrote {out}")


if __name__ == "__main__":
    raise SystemExit(main())
