"""A shell top (t-shirt, long sleeve) under the open jacket or the coat over a draped bottom: does it show through
their panels? drape.SHELLS_UNDER caps the top's trunk under the panels at rest (garments._under_cover), and
pose_character puts what still comes out back under them (character._shell_under_panels); this bench measures both
against builds without them, and the panels' self-crossing edges (`cloth_pose.self_crossings`: making the top a
collider of the panels' drape instead, tried first, let the panels' hem catch on the top's and fold through itself).

    python bench/bench_shell_top_under_jacket.py                # seed 0's subjects 7, 19, 30 (jacket), 25 (coat)
    python bench/bench_shell_top_under_jacket.py --subjects 7 --poses 1 --drape coarse
    python bench/bench_shell_top_under_jacket.py --figure docs/shell_top_under_jacket.png

Subjects are rh-generate's (`sample_recipe(rng_for(seed, "character", s))`, benchmark pool), built as the generator
builds them (the user's drape cache: a cold one simulates each drape, a minute or two at `full`), and once more with
`drape.SHELLS_UNDER` emptied ("without": the top lifted over the bottom's waistband and left there, as tried on
3 December, and no push under them when posed; the panels are the same drape either way). Per subject, build and
pose (the rest pose and the first --poses test poses, `sample_pose(rng_for(seed, "pose", s, "test", j))`), each
cloth mode of `pose_character`:
  over      the top's trunk vertices (all but the sleeves', drape.SLEEVE_GROUPS by each vertex's nearer body vertex;
            the sleeves hang beside the panels by right) lying over the panels' surface (`cloth_pose.layer_depth`
            < 0 within LAYER_REACH, not beyond the panels' open edges, so not in the open front), the farthest (mm);
  seen      of those, how many a camera sees (8 horizontal views around the subject, the ray from 2 mm off the
            vertex along its normal meeting no posed mesh; bench_cloth_pose.seen_around);
  ray       the top's trunk vertices with a panel between them and the skin (the ray from the vertex along its inward
            normal meets the panels within LAYER_REACH), and how many of them are seen: unlike `over` it counts
            vertices whose closest panel point is on the panels' hem (layer_depth leaves those out);
  meet      edges of the top's trunk through the panels' triangles and of the panels through the top's: the surfaces
            through each other between their vertices, which neither vertex count sees;
  in bottom the top's trunk vertices more than 1 mm under the draped bottom's cloth (the push under the panels may
            take the top under the bottom's waistband: a tucked-in look, not a hole);
  cross     the panels' self-crossing edges;
  posing s  `pose_character`'s seconds.
--figure PATH: the first subject in its first test pose, skinned, without | with, rendered full body at 512 px
(rh-generate's standard preset for the test split, 64 spp, Blender's studio light), the jacket's (or coat's) box cut
out at 2x.
The load average is printed with the times: the machine is shared.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

SHELL_TOPS = ("tshirt", "longsleeve")
OUTERS = ("draped_jacket", "draped_coat")  # drape.SHELLS_UNDER's draped kinds
BOTTOMS = ("draped_skirt", "draped_trousers", "draped_shorts", "draped_straight_trousers")


def load() -> str:
    return " ".join(open("/proc/loadavg").read().split()[:3])


def measure(ch, bones: dict, mode: str) -> tuple[str, float]:
    """One line of figures (module docstring) for a built character posed by `bones` in cloth mode `mode`, and the
    posing seconds."""
    from bench_cloth_pose import seen_around
    from rh_common.body_model import ANNY_TOPOLOGY
    from rh_dataset.characters import pose_character
    from rh_dataset.characters.body_features import group_mask
    from rh_dataset.characters.cloth_pose import LAYER_REACH, edges_through, layer_depth, self_crossings
    from rh_dataset.characters.drape import SLEEVE_GROUPS

    t0 = time.perf_counter()
    posed = pose_character(ch, bones, None, mode)
    secs = time.perf_counter() - t0
    d = {m.name: m for m in posed}
    top = next(k for k in SHELL_TOPS if k in d)
    bottom = next(k for k in BOTTOMS if k in d)
    part = ch.part(top)
    nearer = part.blend_vertices[np.arange(len(part.blend_vertices)), np.argmax(part.blend_weights, axis=1)]
    trunk = ~group_mask(ANNY_TOPOLOGY, *SLEEVE_GROUPS)[nearer]
    p = d[top].vertices.astype(np.float64)
    panels, cloth = d[next(k for k in OUTERS if k in d)], d[bottom]
    dep = layer_depth(p, panels.vertices.astype(np.float64), panels.faces, LAYER_REACH)
    out = trunk & (np.nan_to_num(dep, nan=1.0) < 0.0)
    n = d[top].normals.astype(np.float64)
    seen = int(seen_around(p[out], n[out], posed).sum())
    # Out through the panels by a ray: a panel lies between the vertex and the skin (the ray from the vertex along its
    # inward normal meets the panels within LAYER_REACH). Unlike layer_depth this also counts vertices whose closest
    # panel point is on the panels' hem, where the top came through in the pictures.
    inward = trunk & _crosses(p, -n, panels.vertices.astype(np.float64), panels.faces, LAYER_REACH)
    seen_in = int(seen_around(p[inward], n[inward], posed).sum())
    under = layer_depth(p, cloth.vertices.astype(np.float64), cloth.faces, LAYER_REACH)
    inb = trunk & (np.nan_to_num(under, nan=-1.0) > 0.001)
    worst = -1e3 * float(dep[out].min()) if out.any() else 0.0
    cross = self_crossings(panels.vertices, panels.faces)
    # The top's and the panels' surfaces through each other: edges of either (the top's trunk triangles only) passing
    # through a triangle of the other. Between their vertices a panel's ~2 cm triangles can dip through the top.
    tf = np.asarray(d[top].faces)[trunk[np.asarray(d[top].faces)].all(1)]
    pv = panels.vertices.astype(np.float64)
    meet = edges_through(p, tf, pv, panels.faces) + edges_through(pv, panels.faces, p, tf)
    return (f"over {int(out.sum()):4d} ({worst:5.1f} mm) seen {seen:3d} | ray {int(inward.sum()):4d} seen {seen_in:3d} "
            f"| meet {meet:4d} | in bottom {int(inb.sum()):4d} | cross {cross:4d} | posing {secs:5.2f} s"), secs


def _crosses(points: np.ndarray, directions: np.ndarray, vertices: np.ndarray, faces: np.ndarray, reach: float
             ) -> np.ndarray:
    """(P,) bool: does the ray from each point along its unit direction meet the mesh within `reach` metres."""
    import trimesh

    hit = np.zeros(len(points), bool)
    if not len(points):
        return hit
    loc, ray, _ = trimesh.Trimesh(vertices, faces, process=False).ray.intersects_location(points, directions,
                                                                                        multiple_hits=True)
    t = ((loc - points[ray]) * directions[ray]).sum(1)
    hit[ray[(t > 1e-6) & (t < reach)]] = True
    return hit


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", default="7,19,30,25",
                    help="comma-separated benchmark subjects (rh-generate's, at --seed) wearing a shell top under the "
                         "open jacket or the coat over a draped bottom")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed the recipes and poses come from")
    ap.add_argument("--pool", action="store_true",
                    help="--subjects are benchmark pool recipe indices (bench_cloth.draped_recipe's, as "
                         "bench_cloth_layers.py --pool), not rh-generate's: combinations seed 0's 49 do not draw, "
                         "such as the coat over straight trousers (pool recipe 79)")
    ap.add_argument("--poses", type=int, default=3, help="test poses per subject (besides the rest pose)")
    ap.add_argument("--drape", default="full", choices=("full", "coarse"), help="drape level (RenderSettings.drape)")
    ap.add_argument("--modes", nargs="+", default=["skinned", "simulated"], choices=("skinned", "simulated"),
                    help="pose_character's cloth modes to pose in")
    ap.add_argument("--figure", type=Path, default=None,
                    help="write the first subject in its first test pose, without | with, here (PNG)")
    args = ap.parse_args(argv)

    import rh_dataset.characters.character as character_module
    import rh_dataset.characters.drape as drape_module
    from rh_common.body_model import load_anny
    from bench_cloth import benchmark_recipe
    from rh_dataset.characters import build_character
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose

    def posed_with(held: bool, fn):
        """fn() as rh-generate runs it (`held`), or with drape.SHELLS_UNDER emptied (no cap, no push)."""
        saved = drape_module.SHELLS_UNDER
        drape_module.SHELLS_UNDER = saved if held else {}
        try:
            return fn()
        finally:
            drape_module.SHELLS_UNDER = saved

    def build(recipe, held: bool, res: int = 64):
        """The character built as `posed_with` says, and its seconds (the build cache keys on the recipe alone)."""
        character_module._build_cached.cache_clear()
        t0 = time.perf_counter()
        ch = posed_with(held, lambda: build_character(recipe, res, drape=args.drape))
        character_module._build_cached.cache_clear()
        return ch, time.perf_counter() - t0

    print(f"load average at start: {load()}; drape {args.drape}")
    subjects = [int(x) for x in args.subjects.split(",")]
    for s in subjects:
        recipe = benchmark_recipe(s, args.seed, args.pool)
        kinds = [g.kind for g in recipe.garments]
        name = f"{'pool recipe' if args.pool else 'subject'} {s}"
        if not (any(k in kinds for k in OUTERS) and any(k in kinds for k in SHELL_TOPS)
                and any(k in kinds for k in BOTTOMS)):
            ap.error(f"benchmark {name} wears no shell top under the open jacket or the coat over a draped "
                     f"bottom: {kinds}")
        chars = {}
        for way in ("without", "with"):
            chars[way], secs = build(recipe, way == "with")
            print(f"{name} {', '.join(kinds)}: built {way} the cap in {secs:.0f} s (load {load()})",
                  flush=True)
        poses = [("rest", {})] + [(f"test {j} ({p.label})", dict(p.bones)) for j, p in enumerate(
            sample_pose(rng_for(args.seed, "pose", s, "test", j), load_anny()) for j in range(args.poses))]
        for label, bones in poses:
            for mode in args.modes:
                for way, ch in chars.items():
                    line, _ = posed_with(way == "with", lambda: measure(ch, bones, mode))
                    print(f"  {label:16s} {mode:9s} {way:7s} {line}", flush=True)
        print(f"  (load {load()})", flush=True)
        if args.figure and s == subjects[0]:
            first = (chars, recipe)
    if args.figure:
        figure(args.figure, subjects[0], args.seed, *first, posed_with)
    return 0


def figure(out: Path, s: int, seed: int, chars: dict, recipe, posed_with) -> None:
    """`--figure`: each build of `chars` in rh-generate's first test pose of subject `s`, its jacket (or coat) cut out
    at 2x, side by side."""
    from rh_common.body_model import load_anny
    from rh_common.camera import frame_body
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import body_bounds, pose_character
    from rh_dataset.cli import render_settings
    from rh_dataset.generate import rng_for
    from rh_dataset.poses import sample_pose
    from rh_dataset.render.passes import render_frame
    from rh_dataset.spec import load_protocol
    from rh_dataset.variant import load_mitsuba, select_variant
    from subjects_gallery import studio_environment

    select_variant(None)
    env = studio_environment(load_mitsuba())
    test = next(x for x in load_protocol("protocol_a").splits if x.name == "test")
    settings = render_settings("standard", spp=64, aov_spp=4).for_split(test)
    bones = dict(sample_pose(rng_for(seed, "pose", s, "test", 0), load_anny()).bones)
    tiles = []
    for way, ch in chars.items():
        posed = posed_with(way == "with", lambda: pose_character(ch, bones))
        lo, hi = body_bounds(posed)
        cam = frame_body(lo, hi, 512, 512, 30.0, fill=0.94)
        img = render_frame(posed, env, cam, settings, ["image"], seed=s).layers["image"]
        box = cam.project(next(m for m in posed if m.name in OUTERS).vertices.astype(np.float64))
        (x0, y0), (x1, y1) = box.min(0), box.max(0)
        cx, cy, half = 0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.6 * max(x1 - x0, y1 - y0)
        crop = img[max(0, int(cy - half)):int(cy + half), max(0, int(cx - half)):int(cx + half)]
        tiles.append(np.repeat(np.repeat(quantize8(srgb_encode(np.clip(crop * 1.3, 0.0, None))), 2, 0), 2, 1))
    h, w = min(t.shape[0] for t in tiles), min(t.shape[1] for t in tiles)
    write_png(out, np.concatenate([t[:h, :w] for t in tiles], 1))
    print(f"wrote {out}")


if __name__ == "__main__":
    raise SystemExit(main())
