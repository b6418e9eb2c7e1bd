"""Skinned vs simulated draped cloth per frame (rh_dataset/characters/cloth_pose.py): seconds, geometry,
penetration and the image difference, and from them which preset poses cloth which way.

    python bench/bench_cloth_pose.py                                  # 2 subjects x (1 turntable + 3 prior poses)
    python bench/bench_cloth_pose.py --no-render                      # seconds, geometry, penetration only
    python bench/bench_cloth_pose.py --figure docs/cloth_pose.png     # also the picture of the most different pose
    python bench/bench_cloth_pose.py --subjects 1 --no-render --max-body-step 0.01   # another simulation setting
    python bench/bench_cloth_pose.py --kind draped_coat               # another draped kind (DRAPED_KINDS)
    python bench/bench_cloth_pose.py --kind draped_hoodie --simulate-all     # a kind "simulated" leaves skinned
    python bench/bench_cloth_pose.py --kind draped_trousers --drape-fabric   # the trousers in their drape's fabric
    python bench/bench_cloth_pose.py --kind draped_dress --no-lift           # without cloth_pose.lift_over_skin
    python bench/bench_cloth_pose.py --kind draped_coat --lift-all           # lifted, though LIFT_KINDS leaves it

Subjects: the first benchmark-pool recipes that draw `--kind` (default the skirt; recipe_from_seed(derive_seed(
"benchmark", i, --seed)), as bench/bench_cloth.py draws them: bench_cloth.draped_recipe; every skirt drawn is the
draped one). The geometry, body and self columns are that kind's part; the seconds and the image, the whole
character's (every draped part it wears is posed the same way). Poses per
subject: protocol a's turntable frame at 90 degrees (the rest A-pose turned) and the first --poses test poses the
generator draws for that subject (`sample_pose` from `rng_for(seed, "pose", subject, "test", j)`).

Per (subject, pose), both ways of `pose_character(..., cloth=)`:
  seconds   wall time of pose_character (the anny run, every part, the cloth) on this machine, drape cache warm
            (the simulated call also measures the cloth's depth before push_out, one closest-point query); steps:
            the simulation's move + settle steps;
  geometry  the draped part's vertex distance skinned <-> simulated (mean, max) and the Hausdorff distance of the
            two surfaces (trimesh closest points from each one's vertices to the other's triangles, the larger);
  body      cloth-vertex depth under the posed skin (`drape.penetration`, > 0 inside): worst (mm), share inside,
            and the simulation's own worst before the final push_out (raw);
  self      cloth edges that pass through the cloth's own triangles (`cloth_pose.self_crossings`);
  cover     of the body vertices the part covers in the rest pose (`cloth_pose.covers`: the ray out along the
            skin's normal meets it), the share it still covers in the pose: a thigh that left its trouser leg is bare;
  through   of those body vertices that lie inside the part at rest (`cloth_pose.layer_depth` > 0 within 10 cm:
            not a hand hanging beside a skirt), how many lie outside the posed cloth's surface (`layer_depth`
            < 0: within THROUGH_REACH of it, not beyond a hem or cuff) and the farthest (mm): skin that came out
            through the cloth, which a camera on that side sees in place of the fabric (it is not culled under draped
            cloth); and of those, how many a camera sees ("seen": from 2 mm off the skin along its normal, the ray
            towards at least one of 8 cameras around the subject at the height of the point meets none of the
            posed character's meshes; trimesh). Skin pressed into a crease counts as through, but not as seen.
            Both measure the cloth against anny's posed body: for the lifted kinds, posing then tucks the rendered
            body's skin that is out back under the cloth (`cloth_pose.tuck_skin`), which bench/skin_seen.py counts
            in pixels;
  image     512x512 renders at the standard preset (its sampler, spp, env_spp, the pose's scene-class depth, skin
            under clothes culled) under the bundled `interior` map (mean luminance 1), camera framed as the generator
            frames the subject: rh-eval's PSNR (display space over the person's dilated box, over white) of the
            simulated render against the skinned one (same sampler seed), and the standard preset's noise as the
            PSNR of the skinned render at another seed (+3.01 dB = its estimated PSNR against a converged image).
`--simulate-all`: the simulated side simulates every draped kind, also those `cloth_pose.SIMULATED_KINDS` leaves
skinned in every mode (the hoodie's hood; without it its two sides are the same). `--drape-fabric`: simulate with the
fabric each kind was draped with, not `cloth_pose.POSE_FABRIC`'s (the wide-leg trousers as they were simulated
before 3 December).
The decision printed last: a preset simulates the cloth where, on posed frames, the two renders differ by more than
that preset's noise and the simulation costs at most the preset's own render of the frame (the cloth may at most
double a frame's time). The reference preset's render seconds and noise are scaled from standard's measured ones by
the sample counts (time ~ spp, noise variance ~ 1/spp: docs/TRADEOFFS.md), not rendered here.
The load average is printed with every time: the machine is shared.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


from rh_dataset.characters.cloth_pose import SKIN_OUT_REACH  # noqa: E402

THROUGH_REACH = SKIN_OUT_REACH  # metres: skin farther from the cloth is not counted as through it (a limb beside it)


def seen_around(points: np.ndarray, normals: np.ndarray, meshes, n_views: int = 8) -> np.ndarray:
    """(P,) bool: is each skin point seen by at least one of `n_views` cameras around the subject (horizontal,
    far away): the ray from 2 mm off the skin along its normal towards the camera meets none of `meshes` (the posed
    character's triangle meshes, the body included; strands left out)."""
    import trimesh

    seen = np.zeros(len(points), bool)
    tris = [m for m in meshes if hasattr(m, "faces")]
    if not len(points) or not tris:
        return seen
    verts, faces, base = [], [], 0
    for m in tris:
        verts.append(np.asarray(m.vertices, np.float64))
        faces.append(np.asarray(m.faces) + base)
        base += len(m.vertices)
    scene = trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)
    origin = np.asarray(points, np.float64) + 2e-3 * np.asarray(normals, np.float64)
    for k in range(n_views):
        a = 2 * math.pi * k / n_views
        d = np.tile([math.cos(a), math.sin(a), 0.0], (len(points), 1))
        todo = ~seen
        if todo.any():
            seen[todo] = ~scene.ray.intersects_any(origin[todo], d[todo])
    return seen


def rest_and_test_poses(source, subject, split, n: int) -> list[tuple]:
    """[(label, bone deltas or None, root transform or None)]: anny's rest pose, then the split's first `n` poses of
    `subject` as rh-generate draws them (`AnnySubjects.pose`)."""
    return [("rest", None, None)] + [(p.label, dict(p.bones), p.root_transform)
                                     for p in (source.pose(subject, split, j) for j in range(n))]


def subject_bench_args(doc: str, argv: list[str] | None, extra=None):
    """The arguments of the per-subject benches with a before | after picture (bench_shell_folds.py,
    bench_sleeves.py): --seed, --subjects, --poses, --figure, --before, checked; `extra(parser)` adds a bench's own."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    if extra is not None:
        extra(ap)
    ap.add_argument("--seed", type=int, default=0, help="dataset seed whose subjects are used")
    ap.add_argument("--subjects", default="", help="comma-separated subject indices (default: every wearer)")
    ap.add_argument("--poses", type=int, default=2, help="test poses per subject besides the rest pose")
    ap.add_argument("--figure", type=Path, default=None, help="write the first subject's picture here")
    ap.add_argument("--before", type=Path, default=None, help="--figure: a row written in another checkout, put above")
    args = ap.parse_args(argv)
    if args.before is not None and (args.figure is None or not args.before.is_file()):
        raise SystemExit(f"--before {args.before}: needs --figure and an existing PNG written by this script")
    if args.poses < 0:
        raise SystemExit(f"--poses: 0 or more, got {args.poses}")
    return args


def test_source(seed: int):
    """(rh-generate's subjects of protocol a at `seed`, built as at the `standard` preset; protocol a's test split)."""
    from rh_dataset.cli import render_settings
    from rh_dataset.generate.plan import DatasetPlan
    from rh_dataset.generate.subjects import AnnySubjects
    from rh_dataset.spec import load_protocol

    spec = load_protocol("protocol_a")
    source = AnnySubjects(DatasetPlan(out=Path("unused"), spec=spec, settings=render_settings("standard"), seed=seed))
    return source, next(s for s in spec.splits if s.name == "test")


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


def hausdorff(va: np.ndarray, vb: np.ndarray, faces: np.ndarray) -> float:
    """Symmetric Hausdorff distance of two surfaces of one topology, from each one's vertices to the other."""
    import trimesh

    d_ab = trimesh.proximity.closest_point(trimesh.Trimesh(vb, faces, process=False), va)[1]
    d_ba = trimesh.proximity.closest_point(trimesh.Trimesh(va, faces, process=False), vb)[1]
    return float(max(d_ab.max(), d_ba.max()))


def scene_for(character, resolution: int):
    """(camera, emitter dict, exposure, hidden faces) as the generator would: the subject's camera framed on its
    rest pose (`framing_box`, CAMERA_FILL, fov 30 degrees), the `interior` map at mean luminance 1."""
    from rh_common.camera import frame_body
    from rh_dataset.characters import body_bounds, pose_character
    from rh_dataset.generate import exposure_for
    from rh_dataset.generate.subjects import CAMERA_FILL, framing_box
    from rh_dataset.lights import (LightSpec, build_light, bundled_hdris, load_hdri, mitsuba_emitter_dict,
                                   normalised_scale)
    from rh_dataset.render.cull import hidden_faces

    lo, hi = framing_box(*body_bounds(pose_character(character, None, None)))
    cam = frame_body(lo, hi, resolution, resolution, 30.0, fill=CAMERA_FILL)
    path = bundled_hdris()["interior"]
    light = build_light(LightSpec("envmap", "interior", str(path), 0.0, normalised_scale(load_hdri(path)[0])))
    return cam, mitsuba_emitter_dict(light), exposure_for(light), hidden_faces(character)


def render(meshes, scene, settings, seed: int):
    from rh_dataset.render.passes import render_frame

    cam, emitter, _, hidden = scene
    out = render_frame(meshes, emitter, cam, settings, ["image", "mask"], seed, hidden=hidden)
    return out.layers, out.seconds.get("beauty", 0.0) + out.seconds.get("aov", 0.0)


def display(img: np.ndarray, exposure: float) -> np.ndarray:
    from rh_common.colourspace import quantize8, srgb_encode

    return quantize8(srgb_encode(np.clip(img * exposure, 0.0, 1.0)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", default="draped_skirt",
                    help="the draped garment kind measured (one of DRAPED_KINDS); subjects are recipes that draw it")
    ap.add_argument("--subjects", type=int, default=2, help="subjects (benchmark recipes that draw --kind)")
    ap.add_argument("--poses", type=int, default=3, help="test poses of the pose prior per subject")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the recipes and poses come from")
    ap.add_argument("--resolution", type=int, default=512, help="render size")
    ap.add_argument("--no-render", action="store_true", help="skip the renders and the image difference")
    ap.add_argument("--max-body-step", type=float, default=None,
                    help="ClothPoseSettings.max_body_step in metres (default: the setting's)")
    ap.add_argument("--iterations", type=int, default=None,
                    help="ClothPoseSettings.iterations (default: the setting's)")
    ap.add_argument("--simulate-all", action="store_true",
                    help="simulate every draped kind, also those cloth_pose.SIMULATED_KINDS leaves skinned")
    ap.add_argument("--drape-fabric", action="store_true",
                    help="simulate every kind with the fabric it was draped with (cloth_pose.POSE_FABRIC emptied: the "
                         "wide-leg trousers as simulated before 3 December)")
    ap.add_argument("--no-lift", action="store_true",
                    help="pose the draped cloth without cloth_pose.lift_over_skin (as before 4 December): the "
                         "through / seen columns with and without it are how LIFT_KINDS was chosen")
    ap.add_argument("--lift-all", action="store_true",
                    help="also lift --kind's cloth over the skin if cloth_pose.LIFT_KINDS leaves it unlifted")
    ap.add_argument("--figure", type=Path, default=None,
                    help="write skinned | simulated of the pose whose surfaces differ most (front, then its left side)")
    args = ap.parse_args(argv)

    from bench_cloth import draped_recipe
    from bench_tradeoff import Scorer

    from rh_common.body_model import load_anny
    from rh_dataset.characters import build_character, pose_character
    from rh_dataset.characters.body import body_topology, run_anny
    from rh_dataset.mesh import vertex_normals
    from rh_dataset.characters.cloth_pose import covers, layer_depth, self_crossings, skin_inside
    from rh_dataset.characters.drape import DRAPED_KINDS, penetration
    from rh_dataset.cli import render_settings
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose, turntable
    from rh_dataset.presets import load_presets

    from rh_dataset.characters.cloth_pose import ClothPoseSettings

    if args.kind not in DRAPED_KINDS:
        ap.error(f"--kind must be one of {DRAPED_KINDS}, got {args.kind!r}")
    import rh_dataset.characters.cloth_pose as cloth_pose

    simulated_kinds = cloth_pose.SIMULATED_KINDS
    if args.simulate_all:
        cloth_pose.SIMULATED_KINDS = DRAPED_KINDS  # read by simulated_parts at each call
    if args.drape_fabric:
        cloth_pose.POSE_FABRIC = {}  # read by pose_fabric at each call
    changed = {k: v for k, v in (("max_body_step", args.max_body_step), ("iterations", args.iterations))
               if v is not None}
    cloth_settings = ClothPoseSettings(**changed)
    presets = load_presets()
    standard = render_settings("standard")
    faces = body_topology().faces
    rows, figure_case = [], None
    index = 0
    print(f"load average at start: {load()}; kind {args.kind}; simulation settings {cloth_settings}")
    for _ in range(args.subjects):
        recipe = draped_recipe(index, args.seed, args.kind)
        index = recipe.index + 1
        character = build_character(recipe, 512)
        if args.no_lift:  # the draped parts posed without cloth_pose.lift_over_skin
            character = dataclasses.replace(character, parts=list(
                dataclasses.replace(p, inside_skin=None, inside_depth=None) for p in character.parts))
        kinds = [p.name for p in character.parts if p.name in DRAPED_KINDS]
        assert args.kind in kinds, (args.kind, kinds)
        rest = pose_character(character, None, None, "simulated")  # the drape (cached on disk) and kernels, not timed
        rest_body = run_anny(character.phenotype)["vertices"]
        part_faces = next(p for p in character.parts if p.name == args.kind).faces
        rest_part = next(x for x in rest if x.name == args.kind).vertices
        rest_normals = vertex_normals(rest_body, faces)
        under = np.flatnonzero(covers(rest_part, part_faces, rest_body, rest_normals))  # the skin it covers at rest
        # Of it, the skin inside the part at rest (a hand hanging beside a skirt is covered by that ray, not inside).
        inside = skin_inside(rest_part, part_faces, rest_body, rest_normals)
        if args.lift_all and not args.no_lift:  # lift the measured kind's cloth too if LIFT_KINDS leaves it
            character = dataclasses.replace(character, parts=[
                dataclasses.replace(p, inside_skin=inside) if p.name == args.kind and p.inside_skin is None else p
                for p in character.parts])
        scene = None if args.no_render else scene_for(character, args.resolution)
        poses = [("turntable", turntable(4)[1])]
        poses += [(f"test {j}", sample_pose(rng_for(args.seed, "pose", recipe.index, "test", j), load_anny()))
                  for j in range(args.poses)]
        print(f"\nsubject {recipe.index}: draped {kinds}, phenotype "
              f"{ {k: round(v, 2) for k, v in recipe.phenotype.items()} }")
        for name, pose in poses:
            bones = dict(pose.bones)
            out, stats = {}, {}
            for mode in ("skinned", "simulated"):
                t = time.perf_counter()
                meshes = pose_character(character, bones, pose.root_transform, mode,
                                        cloth_stats=stats if mode == "simulated" else None,
                                        cloth_settings=cloth_settings)
                out[mode] = (meshes, time.perf_counter() - t, load())
            run = run_anny(character.phenotype, bones)
            m = pose.root_transform
            body = run["vertices"] @ m[:3, :3].T + m[:3, 3]
            normals = vertex_normals(body, faces)
            row = {"subject": recipe.index, "pose": f"{name} ({pose.label})", "posed": name != "turntable",
                   "t_skin": out["skinned"][1], "t_sim": out["simulated"][1], "load": out["simulated"][2],
                   "steps": stats.get("move_steps", 0) + stats.get("settle_steps", 0),
                   "raw_mm": 1e3 * max(stats.get("depth_before_push_m", 0.0), 0.0)}
            for kind in (args.kind,):
                part = next(p for p in character.parts if p.name == kind)
                a = next(x for x in out["skinned"][0] if x.name == kind).vertices.astype(np.float64)
                b = next(x for x in out["simulated"][0] if x.name == kind).vertices.astype(np.float64)
                d = np.linalg.norm(a - b, axis=1)
                row.update(mean_mm=1e3 * d.mean(), max_mm=1e3 * d.max(), haus_mm=1e3 * hausdorff(a, b, part.faces))
                for mode, v in (("skin", a), ("sim", b)):
                    pen = penetration(body, faces, v)
                    row[f"pen_{mode}_mm"] = 1e3 * max(float(pen.max()), 0.0)
                    row[f"in_{mode}_pct"] = 100.0 * float((pen > 0).mean())
                    row[f"self_{mode}"] = self_crossings(v, part.faces)
                    row[f"cover_{mode}_pct"] = 100.0 * float(covers(v, part.faces, body[under], normals[under]).mean())
                    depth = layer_depth(body[inside], v, part.faces, near=THROUGH_REACH)
                    through = inside[np.isfinite(depth) & (depth < 0)]
                    row[f"through_{mode}"] = len(through)
                    row[f"through_{mode}_mm"] = -1e3 * float(np.nanmin(depth)) if len(through) else 0.0
                    meshes = out["skinned" if mode == "skin" else "simulated"][0]
                    row[f"seen_{mode}"] = int(seen_around(body[through], normals[through], meshes).sum())
            if scene is not None:
                depth = presets["standard"].depth_for("posed-envmap" if row["posed"] else "apose-envmap")
                st = dataclasses.replace(standard, max_depth=depth)
                ref, row["t_render"] = render(out["skinned"][0], scene, st, 1)
                sim, _ = render(out["simulated"][0], scene, st, 1)
                other, _ = render(out["skinned"][0], scene, st, 2)
                scorer = Scorer({"image": ref["image"], "mask": ref["mask"]}, scene[2])
                row["psnr_sim"] = scorer.psnr(sim["image"])
                row["psnr_noise"] = scorer.psnr(other["image"])
                if figure_case is None or row["haus_mm"] > figure_case[0]:
                    figure_case = (row["haus_mm"], character, bones, pose, ref, sim, scene, st)
            rows.append(row)
            print(_line(row), flush=True)
    _summary(rows, presets, standard)
    if args.kind not in simulated_kinds:
        print(f"note: the generator's \"simulated\" mode leaves {args.kind} skinned (cloth_pose.SIMULATED_KINDS "
              f"{simulated_kinds}){'; measured here with --simulate-all' if args.simulate_all else ''}")
    if args.figure is not None and figure_case is not None:
        _figure(args.figure, figure_case, cloth_settings)
    return 0


HEAD = ("subject pose                  skin s   sim s steps  mean mm  max mm  Haus mm | body mm skin/sim (sim raw)"
        "  inside % skin/sim  self skin/sim | cover % skin/sim | through, seen, mm: skin / sim | PSNR sim  noise  load")


def _line(r: dict) -> str:
    img = (f" | {r['psnr_sim']:8.2f} {r['psnr_noise']:6.2f}" if "psnr_sim" in r else " |      -      -")
    return (f"{r['subject']:7d} {r['pose']:20s} {r['t_skin']:7.2f} {r['t_sim']:7.1f} {r['steps']:5d} "
            f"{r['mean_mm']:8.1f} "
            f"{r['max_mm']:7.1f} {r['haus_mm']:8.1f} | {r['pen_skin_mm']:7.2f} {r['pen_sim_mm']:7.2f} "
            f"({r['raw_mm']:5.2f})   "
            f"{r['in_skin_pct']:6.2f} {r['in_sim_pct']:6.2f}   {r['self_skin']:5d} {r['self_sim']:5d} | "
            f"{r['cover_skin_pct']:5.1f} {r['cover_sim_pct']:5.1f} | {r['through_skin']:4d} {r['seen_skin']:4d} "
            f"{r['through_skin_mm']:5.1f} {r['through_sim']:4d} {r['seen_sim']:4d} {r['through_sim_mm']:5.1f}{img}  "
            f"{r['load']}")


def _summary(rows: list[dict], presets: dict, standard) -> None:
    print("\n" + HEAD)
    for r in rows:
        print(_line(r))
    posed = [r for r in rows if r["posed"]]
    if not posed:
        return
    med = lambda key: float(np.median([r[key] for r in posed]))  # noqa: E731
    print(f"\nposed frames ({len(posed)}): median seconds skinned {med('t_skin'):.2f}, simulated {med('t_sim'):.1f}; "
          f"median Hausdorff {med('haus_mm'):.0f} mm (worst {max(r['haus_mm'] for r in posed):.0f}); worst cloth "
          f"depth in the body skinned {max(r['pen_skin_mm'] for r in posed):.2f} mm, simulated "
          f"{max(r['pen_sim_mm'] for r in posed):.2f} mm (before push_out {max(r['raw_mm'] for r in posed):.2f} mm);"
          f" self-crossing edges skinned "
          f"{sum(r['self_skin'] for r in posed)}, simulated {sum(r['self_sim'] for r in posed)}; skin covered at rest "
          f"still covered, worst pose: skinned {min(r['cover_skin_pct'] for r in posed):.1f} %, simulated "
          f"{min(r['cover_sim_pct'] for r in posed):.1f} %; skin through the cloth, all posed frames: skinned "
          f"{sum(r['through_skin'] for r in posed)} vertices ({sum(r['seen_skin'] for r in posed)} seen; worst "
          f"{max(r['through_skin_mm'] for r in posed):.1f} mm out), simulated {sum(r['through_sim'] for r in posed)} "
          f"({sum(r['seen_sim'] for r in posed)} seen; worst {max(r['through_sim_mm'] for r in posed):.1f} mm)"
          f"  (load {load()})")
    if "psnr_sim" not in posed[0]:
        return
    diff_db = med("psnr_sim")
    noise_db = med("psnr_noise") + 10 * math.log10(2.0)  # one render against a converged one
    t_render = med("t_render")
    extra = med("t_sim") - med("t_skin")
    print(f"image: simulated vs skinned median PSNR {diff_db:.2f} dB over the person (worst "
          f"{min(r['psnr_sim'] for r in posed):.2f}); standard's own noise {noise_db:.2f} dB; standard render "
          f"{t_render:.1f} s a frame; the simulation adds {extra:.1f} s a posed frame")
    print("\ndecision (simulate where the renders differ by more than the preset's noise and the simulation costs "
          "at most the preset's render):")
    for name, p in presets.items():
        scale = p.spp / standard.spp
        t = t_render * scale  # beauty time ~ spp; the AOV pass is a small share (README's cost table)
        noise = noise_db + 10 * math.log10(scale)
        visible = diff_db < noise
        mode = "simulated" if visible and extra <= t else "skinned"
        how = "measured" if name == "standard" else f"scaled by spp {p.spp}/{standard.spp}"
        print(f"  {name:9s} render ~{t:7.1f} s ({how}), noise ~{noise:5.1f} dB: difference "
              f"{'above' if visible else 'within'} its noise, simulation {extra:.0f} s "
              f"{'<=' if extra <= t else '>'} its render -> {mode}  (presets.json says {p.cloth})")


def _figure(path: Path, case, cloth_settings) -> None:
    """Front (the two standard renders) and side (rendered here, same settings) of skinned | simulated, each row
    cropped to the person (both renders' coverage, plus a margin)."""
    from rh_common.imageio import write_png
    from rh_dataset.characters import pose_character
    from rh_dataset.poses.pose import rotation_about_z

    _, character, bones, pose, front_skin, front_sim, scene, st = case
    exposure = scene[2]
    turn = rotation_about_z(90.0) @ pose.root_transform
    side = [render(pose_character(character, bones, turn, mode, cloth_settings=cloth_settings), scene, st, 1)[0]
            for mode in ("skinned", "simulated")]
    rows = []
    for pair in ((front_skin, front_sim), tuple(side)):
        cover = np.maximum(pair[0]["mask"], pair[1]["mask"]) > 0.01
        ys, xs = np.nonzero(cover)
        m = 12
        y0, y1 = max(ys.min() - m, 0), min(ys.max() + m + 1, cover.shape[0])
        x0, x1 = max(xs.min() - m, 0), min(xs.max() + m + 1, cover.shape[1])
        rows.append([display(x["image"][y0:y1, x0:x1], exposure) for x in pair])
    h = max(t.shape[0] for r in rows for t in r)
    pad = lambda t: np.pad(t, ((0, h - t.shape[0]), (0, 0), (0, 0)), constant_values=255)  # noqa: E731
    img = np.concatenate([pad(t) for r in rows for t in r], axis=1)
    write_png(path, img)
    print(f"wrote {path} ({img.shape[1]}x{img.shape[0]}: front skinned | front simulated | side skinned | side "
          f"simulated; subject pose {pose.label})")


if __name__ == "__main__":
    raise SystemExit(main())
