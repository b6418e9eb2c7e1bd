"""Gallery of the hair styles and colours on benchmark subjects: head-and-shoulders renders (beauty, albedo layer).

    python bench/subjects_gallery.py [--out docs/subjects.png] [--size 256] [--spp 64]
    python bench/subjects_gallery.py --headwear [--out docs/headwear.png] [--size 512] [--spp 20]
    python bench/subjects_gallery.py --benchmark 12 [--out docs/benchmark_subjects.png] [--size 512] [--spp 64]

--benchmark N: the first N subjects of protocol a exactly as `rh-generate` makes them (seed 0, their own recipes:
hair, garments, draped cloth, headwear), each in its first test pose (the pose prior's draw for that frame), seen
full-body from the front, in two rows; beside it (`<out>_heads.png`) one row of head-and-shoulders close-ups of the
same subjects in the rest pose from the front-left, rendered at --size and halved (2x2 box average).

--headwear: the first two benchmark-seed subjects (seeds 2, 4, ...) whose recipe draws each headwear kind (cap,
brimmed_hat, headscarf, glasses), unmodified (their own hair, clothes and headwear colours), one column per kind,
beauty only, from the front-left (top row) and the left (bottom row).

Each tile is a benchmark subject (recipe from an even seed) with its hair style and colour replaced so that every
style (rh_dataset.characters.HAIR_STYLES) appears once, colours cycling through black, brown, blonde, auburn and
grey. Rendered by the dataset renderer (`render_frame`: path tracer + AOV pass) in the rest pose under Blender's
studio HDRI, seen from the front-left. Top row: the beauty image (sRGB, exposure 1.3); bottom: the albedo layer.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's code, not an installed copy's

STUDIO_HDRI = Path("/usr/share/blender/datafiles/studiolights/world/studio.exr")
COLOURS = {"black": (20, 16, 14), "brown": (80, 54, 36), "blonde": (205, 170, 110), "auburn": (130, 60, 32),
           "grey": (170, 168, 165)}


def studio_environment(mi) -> dict:
    """The galleries' light: Blender's studio HDRI, turned so its key light falls from the front-left."""
    return {"type": "envmap", "filename": str(STUDIO_HDRI),
            "to_world": mi.ScalarTransform4f().rotate([0, 0, 1], 200).rotate([1, 0, 0], 90)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("docs/subjects.png"),
                   help="the PNG written (--benchmark: docs/benchmark_subjects.png unless given)")
    p.add_argument("--size", type=int, default=256, help="tile size in pixels")
    p.add_argument("--spp", type=int, default=64, help="samples per pixel of each render")
    p.add_argument("--headwear", action="store_true", help="the headwear gallery instead of the hair one")
    p.add_argument("--benchmark", type=int, default=0, metavar="N",
                   help="the first N protocol-a subjects as generated (full body, posed; head close-ups)")
    args = p.parse_args()
    if args.benchmark and args.headwear:
        p.error("--benchmark and --headwear are two galleries: choose one")
    if args.benchmark and args.out == Path("docs/subjects.png"):
        args.out = Path("docs/benchmark_subjects.png")

    from rh_common.camera import Camera
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import HAIR_STYLES, HairSpec, build_character, pose_character, recipe_from_seed
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import load_mitsuba, select_variant

    select_variant(None)
    env = studio_environment(load_mitsuba())
    if args.headwear:
        return _headwear(args, env)
    if args.benchmark:
        return _benchmark(args, env)
    names = list(COLOURS)
    tiles = []
    for k, style in enumerate(HAIR_STYLES):
        colour = names[k % len(names)]
        recipe = recipe_from_seed(2 * (k + 1), "benchmark", k)
        # Bare-headed, so that the style shows (a scarf hides all of it, a cap most); --headwear has its own.
        recipe = dataclasses.replace(recipe, hair=HairSpec(style, tuple(c / 255 for c in COLOURS[colour])),
                                     headwear=())
        t = time.perf_counter()
        posed = pose_character(build_character(recipe, 512))
        hair = np.concatenate([m.vertices for m in posed if hasattr(m, "fibre")])
        c = np.array([np.median(hair[:, 0]), np.median(hair[:, 1]), hair[:, 2].max() - 0.17])
        cam = Camera(args.size, args.size, 30.0, tuple(map(float, c + [0.4, -0.8, 0.08])), tuple(map(float, c)))
        out = render_frame(posed, env, cam, RenderSettings(spp=args.spp, aov_spp=16, max_depth=8),
                           ["image", "albedo"], seed=k)
        print(f"{style:10s} {colour:7s} {sum(len(m.points) for m in posed if hasattr(m, 'fibre'))} strands, "
              f"{time.perf_counter() - t:.1f} s", flush=True)
        img = quantize8(srgb_encode(np.clip(out.layers["image"] * 1.3, 0.0, None)))
        alb = quantize8(srgb_encode(out.layers["albedo"]))
        tiles.append(np.concatenate([img, alb], 0))
    write_png(args.out, np.concatenate(tiles, 1))
    print(f"wrote {args.out}")


def _headwear(args, env) -> None:
    from rh_common.camera import Camera
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import build_character, pose_character, recipe_from_seed
    from rh_dataset.characters.recipe import HEADWEAR_KINDS
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings

    picks: dict[str, list] = {k: [] for k in HEADWEAR_KINDS}
    k = 0
    while any(len(v) < 2 for v in picks.values()):
        k += 1
        r = recipe_from_seed(2 * k, "benchmark", k)
        kinds = [h.kind for h in r.headwear]
        main = next((x for x in kinds if x != "glasses"), "glasses" if kinds else None)
        if main is not None and len(picks[main]) < 2:
            picks[main].append(r)
    columns = []
    for kind in HEADWEAR_KINDS:
        rows = []
        for i, recipe in enumerate(picks[kind]):
            t = time.perf_counter()
            posed = pose_character(build_character(recipe, 512))
            body = next(m for m in posed if m.name == "body").vertices
            top = float(body[:, 2].max())
            head = body[body[:, 2] > top - 0.25]
            c = np.array([float(np.median(head[:, 0])), float(np.median(head[:, 1])), top - 0.13])
            offset = [0.4, -0.8, 0.08] if i == 0 else [0.9, -0.05, 0.05]
            cam = Camera(args.size, args.size, 30.0, tuple(map(float, c + offset)), tuple(map(float, c)))
            out = render_frame(posed, env, cam, RenderSettings(spp=args.spp, aov_spp=4, max_depth=8), ["image"],
                               seed=k)
            worn = "+".join(h.kind for h in recipe.headwear)
            print(f"{kind:12s} seed {recipe.seed:<20d} {worn:20s} hair {recipe.hair.style:9s} "
                  f"{time.perf_counter() - t:.1f} s", flush=True)
            rows.append(quantize8(srgb_encode(np.clip(out.layers["image"] * 1.3, 0.0, None))))
        columns.append(np.concatenate(rows, 0))
    write_png(args.out, np.concatenate(columns, 1))
    print(f"wrote {args.out}")


def _benchmark(args, env) -> None:
    from rh_common.camera import Camera, frame_body
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png
    from rh_dataset.characters import body_bounds, pose_character
    from rh_dataset.generate.plan import DatasetPlan
    from rh_dataset.generate.subjects import AnnySubjects
    from rh_dataset.cli import render_settings
    from rh_dataset.render.passes import render_frame
    from rh_dataset.spec import load_protocol

    spec = load_protocol("protocol_a")
    n = args.benchmark
    if not 1 <= n <= spec.subjects:
        raise SystemExit(f"--benchmark: 1..{spec.subjects} subjects, got {n}")
    source = AnnySubjects(DatasetPlan(out=Path("unused"), spec=spec, settings=render_settings("standard")))
    test = next(s for s in spec.splits if s.name == "test")
    # The standard preset's path depths for the test split (its scene class), at the gallery's sample count.
    settings = render_settings("standard", spp=args.spp, aov_spp=4).for_split(test)
    full, heads = [], []
    for s in range(n):
        t = time.perf_counter()
        subject = source.subject(s)
        pose = source.pose(subject, test, 0)
        posed = source.meshes(subject, pose)
        lo, hi = body_bounds(posed)
        cam = frame_body(lo, hi, args.size, args.size, 30.0, fill=0.94)
        out = render_frame(posed, env, cam, settings, ["image"], seed=s)
        full.append(quantize8(srgb_encode(np.clip(out.layers["image"] * 1.3, 0.0, None))))
        rest = pose_character(subject.character, None, None)
        body = next(m for m in rest if m.name == "body").vertices
        top = float(body[:, 2].max())
        head = body[body[:, 2] > top - 0.25]
        c = np.array([float(np.median(head[:, 0])), float(np.median(head[:, 1])), top - 0.16])
        cam = Camera(args.size, args.size, 30.0, tuple(map(float, c + [0.45, -0.95, 0.08])), tuple(map(float, c)))
        out = render_frame(rest, env, cam, settings, ["image"], seed=s)
        img = np.clip(out.layers["image"] * 1.3, 0.0, None)
        img = 0.25 * (img[0::2, 0::2] + img[1::2, 0::2] + img[0::2, 1::2] + img[1::2, 1::2])
        heads.append(quantize8(srgb_encode(img)))
        r = subject.record
        worn = "+".join(g["kind"] for g in r["garments"]) + "".join("+" + h["kind"] for h in r.get("headwear") or [])
        print(f"subject {s:2d} hair {r['hair']['style']:9s} {worn:45s} {time.perf_counter() - t:6.1f} s",
              flush=True)
    cols = (n + 1) // 2
    full += [np.zeros_like(full[0])] * (2 * cols - n)
    write_png(args.out, np.concatenate([np.concatenate(full[:cols], 1), np.concatenate(full[cols:], 1)], 0))
    heads_out = args.out.with_name(args.out.stem + "_heads.png")
    write_png(heads_out, np.concatenate(heads, 1))
    print(f"wrote {heads_out}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
