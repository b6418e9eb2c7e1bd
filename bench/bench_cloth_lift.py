"""How `cloth_pose.lift_over_skin` should move draped cloth over skin that came out through it: the direction
(`LIFT_WAYS`) and the reach (`LIFT_REACH`), each measured against the cloth as `push_out` leaves it.

    python bench/bench_cloth_lift.py                                  # the test body's leg in 4 seated poses
    python bench/bench_cloth_lift.py --kind draped_dress --subjects 2 --poses 1 2    # benchmark recipes' test poses
    python bench/bench_cloth_lift.py --reaches 0.008 0.015 0.025      # other reaches
    python bench/bench_cloth_lift.py --kind draped_trousers --subjects 1 --poses 2 --figure docs/cloth_lift_trousers.png

Cases. Default: the tests' body (tests/test_cloth_pose.py's PHENO) in wide trousers at the `coarse` drape level,
its left thigh raised and knee bent (hip, knee degrees: -90/90, -90/0, -60/60, -110/120). With `--kind K`: the first
`--subjects` benchmark recipes that draw K (bench_cloth.draped_recipe, seed 0, full drapes) in their test poses
`--poses` (the generator's `sample_pose` draws), posed with the character's other parts as pose_character poses them.
Each case: the garment skinned (`drape.bind_loose`) and pushed out (`drape.push_out`), then lifted every way at
every reach. Printed per variant, summed over the cases:
  through   skin vertices inside the cloth at rest (`cloth_pose.skin_inside`) that lie outside it posed (within 3 cm,
            not beyond a hem), and of them "bare": those not inside the body itself (the ray out along the skin's
            normal crosses the body an even number of times; trimesh): skin a camera could see;
  seen      with --kind: of those through, how many a camera sees (bench_cloth_pose.seen_around, 8 cameras around);
  self      cloth edges through the cloth's own triangles (`cloth_pose.self_crossings`);
  moved     cloth vertices the lift moved more than 1 cm;
  seconds   the lift's wall time, summed (on this machine; the load average is printed).
`--figure PATH` (with --kind): the last case rendered as pose_character poses it, unlifted (top row) and lifted
(bottom row), front, left and right, cropped to the hips and legs (standard preset at 64 spp, the subjects gallery's
studio light, 384 px a view).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

TEST_BODY = {"gender": 1.0, "age": 0.6, "muscle": 0.5, "weight": 0.5, "height": 0.5, "proportions": 0.5}
SEATS = ((-90, 90), (-90, 0), (-60, 60), (-110, 120))  # (hip, knee) degrees about the body's +X axis
THROUGH_NEAR = 0.03


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def seated(hip: float, knee: float) -> dict[str, np.ndarray]:
    from rh_dataset.poses.joints import rotation_about

    out = {}
    for bone, deg in (("upperleg01.L", hip), ("lowerleg01.L", knee)):
        m = np.eye(4)
        m[:3, :3] = rotation_about(np.array([1.0, 0.0, 0.0]), float(deg))
        out[bone] = m
    return out


def cases(args):
    """Yield (label, garment, phenotype, bone deltas, other posed meshes or None)."""
    from rh_dataset.characters.drape import drape_garment, drape_settings

    if args.kind is None:
        g = drape_garment("draped_trousers", TEST_BODY, drape_settings("draped_trousers", "coarse"))
        for hip, knee in SEATS:
            yield f"test body, hip {hip} knee {knee}", g, TEST_BODY, seated(hip, knee), None
        return
    import dataclasses

    from bench_cloth import draped_recipe

    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose

    index = 0
    for _ in range(args.subjects):
        recipe = draped_recipe(index, 0, args.kind)
        index = recipe.index + 1
        ch = build_character(recipe, 512)
        ch = dataclasses.replace(ch, parts=[dataclasses.replace(p, inside_skin=None, inside_depth=None)
                                            for p in ch.parts])
        part = next(p for p in ch.parts if p.name == args.kind)
        g = drape_garment(args.kind, ch.phenotype, part.drape)
        for j in args.poses:
            pose = sample_pose(rng_for(0, "pose", recipe.index, "test", j), load_anny())
            bones = dict(pose.bones)
            others = [m for m in pose_character(ch, bones, None, "skinned") if m.name != args.kind]
            yield f"subject {recipe.index}, test {j} ({pose.label})", g, ch.phenotype, bones, others


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", default=None,
                    help="a draped kind worn by benchmark recipes (default: the test body in coarse trousers)")
    ap.add_argument("--subjects", type=int, default=2, help="with --kind: benchmark recipes that draw it")
    ap.add_argument("--poses", type=int, nargs="+", default=[0, 1, 2], help="with --kind: test pose numbers")
    ap.add_argument("--reaches", type=float, nargs="+", default=None,
                    help="LIFT_REACH values in metres (default: the module's)")
    ap.add_argument("--figure", type=Path, default=None,
                    help="with --kind: write the last case's renders, unlifted over lifted, to this PNG")
    args = ap.parse_args(argv)
    if args.figure is not None and args.kind is None:
        ap.error("--figure needs --kind (a benchmark recipe to render)")

    import trimesh

    from bench_cloth_pose import seen_around

    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.mesh import vertex_normals
    from rh_dataset.characters.cloth_pose import (LIFT_REACH, LIFT_WAYS, layer_depth, lift_over_skin,
                                                  self_crossings, skin_inside)
    from rh_dataset.characters.drape import bind_loose, push_clearance, push_out, skin_points

    reaches = args.reaches or [LIFT_REACH]
    variants = [("unlifted", None, None)] + [(f"{w}, reach {1e3 * r:.0f} mm", w, r) for w in LIFT_WAYS for r in reaches]
    faces = body_topology().faces
    totals = {name: np.zeros(6) for name, _, _ in variants}
    print(f"load average at start: {load()}")
    last = None
    for label, g, phenotype, bones, others in cases(args):
        last = bones
        rest = run_anny(phenotype)["vertices"]
        inside = skin_inside(g.vertices, g.faces, rest, vertex_normals(rest, faces))
        run = run_anny(phenotype, bones)
        body = run["vertices"]
        normals = vertex_normals(body, faces)
        body_mesh = trimesh.Trimesh(body, faces, process=False)
        clearance = push_clearance(g.kind)
        plain = push_out(skin_points(bind_loose(g, phenotype), run["bone_poses"], run["rest_bone_poses"]),
                         body, normals, faces, clearance)
        line = f"{label}:"
        for name, way, reach in variants:
            t = time.perf_counter()
            v = plain if way is None else lift_over_skin(plain, g.faces, inside, body, normals, faces, clearance,
                                                         reach=reach, way=way)
            seconds = time.perf_counter() - t
            depth = layer_depth(body[inside], v, g.faces, near=THROUGH_NEAR)
            through = inside[np.isfinite(depth) & (depth < 0)]
            hits = body_mesh.ray.intersects_id(body[through] + 1e-3 * normals[through], normals[through],
                                               multiple_hits=True)[1]
            bare = int((np.bincount(hits, minlength=len(through)) % 2 == 0).sum())
            seen = 0
            if others is not None:
                cloth = types.SimpleNamespace(name=g.kind, vertices=v, faces=g.faces)
                seen = int(seen_around(body[through], normals[through], others + [cloth]).sum())
            moved = int((np.linalg.norm(v - plain, axis=1) > 0.01).sum())
            row = np.array([len(through), bare, seen, self_crossings(v, g.faces), moved, seconds])
            totals[name] += row
            line += f" | {name}: {len(through)}/{bare}" + (f"/{seen}" if others is not None else "")
        print(line + f"  (load {load()})", flush=True)
    head = ["variant", "through", "bare"] + (["seen"] if args.kind else []) + ["self-crossing edges",
                                                                               "moved > 1 cm", "lift seconds"]
    print("\nsummed over the cases: " + " | ".join(head))
    for name, t in totals.items():
        seen = f" {int(t[2]):5d}" if args.kind else ""
        print(f"  {name:28s} {int(t[0]):6d} {int(t[1]):6d}{seen} {int(t[3]):6d} {int(t[4]):6d} {t[5]:8.2f}")
    print(f"(load {load()})")
    if args.figure is not None and last is not None:
        figure(args.figure, args.kind, args.subjects, last)
    return 0


def figure(path: Path, kind: str, subjects: int, bones) -> None:
    """Unlifted over lifted renders of the last subject drawing `kind` in the pose `bones`."""
    import dataclasses

    from bench_cloth import draped_recipe
    from subjects_gallery import studio_environment

    from rh_common.camera import frame_body
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import body_bounds, build_character, pose_character
    from rh_dataset.cli import render_settings
    from rh_dataset.render.passes import render_frame
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import load_mitsuba, select_variant

    index, recipe = 0, None
    for _ in range(subjects):
        recipe = draped_recipe(index, 0, kind)
        index = recipe.index + 1
    select_variant(None)
    env = studio_environment(load_mitsuba())
    test = next(x for x in load_protocol("protocol_a").splits if x.name == "test")
    settings = render_settings("standard", spp=64, aov_spp=4).for_split(test)
    lifted = build_character(recipe, 1024)
    plain = dataclasses.replace(lifted, parts=[dataclasses.replace(p, inside_skin=None, inside_depth=None)
                                               for p in lifted.parts])
    rows = []
    for character in (plain, lifted):
        posed = pose_character(character, bones, None, "skinned")
        lo, hi = body_bounds(posed)
        top, bottom = lo.copy(), hi.copy()
        top[2] = lo[2] + 0.15 * (hi[2] - lo[2])
        bottom[2] = lo[2] + 0.62 * (hi[2] - lo[2])
        cam = frame_body(top, bottom, 384, 384, 30.0, fill=0.9)
        centre = np.array(cam.target)
        reach = np.linalg.norm(np.array(cam.origin) - centre)
        views = []
        for deg in (0, 90, 270):  # front, the subject's left, right
            a = np.radians(deg)
            origin = centre + reach * np.array([-np.sin(a), -np.cos(a), 0.0])
            img = render_frame(posed, env, dataclasses.replace(cam, origin=tuple(map(float, origin))), settings,
                               ["image"], seed=recipe.index).layers["image"]
            views.append(quantize8(srgb_encode(np.clip(img * 1.3, 0, None))))
        rows.append(np.concatenate(views, 1))
    write_png(path, np.concatenate(rows, 0))
    print(f"wrote {path}: subject {recipe.index}, unlifted (top) over lifted (bottom), front | left | right")


if __name__ == "__main__":
    raise SystemExit(main())
