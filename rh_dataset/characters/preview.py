"""Contact sheet of sampled characters in the rest pose, rendered with Mitsuba 3 under Blender's studio HDRI.

    python -m rh_dataset.characters.preview --n 8 --out /tmp/chars.png [--pool benchmark] [--seed 0] [--spp 16]

A look-development tool, not the dataset renderer: it builds its own small scene dict.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from rh_common.colourspace import quantize8, srgb_encode
from rh_common.imageio import write_png

from .character import PosedMesh, body_bounds, build_character, mitsuba_texcoords, pose_character
from .recipe import POOLS
from .recipe_draws import sample_recipe

__all__ = ["render_preview", "main"]

STUDIO_HDRI = Path("/usr/share/blender/datafiles/studiolights/world/studio.exr")


def _mi():
    from ..variant import ensure_variant

    return ensure_variant()


def _mesh(mi, pm: PosedMesh):
    bsdf = {
        "type": "principled",
        "base_color": {"type": "bitmap", "bitmap": mi.Bitmap(np.array(pm.material.albedo, dtype=np.float32, copy=True)), "raw": True},
        "roughness": max(pm.material.roughness, 0.05),
        "specular": pm.material.specular,
    }
    if pm.material.sheen > 0.0:
        bsdf.update(sheen=pm.material.sheen, sheen_tint=pm.material.sheen_tint)
    if pm.material.clearcoat > 0.0:
        bsdf.update(clearcoat=pm.material.clearcoat, clearcoat_gloss=pm.material.clearcoat_gloss)
    if pm.material.two_sided:
        bsdf = {"type": "twosided", "bsdf": bsdf}
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    mesh = mi.Mesh(pm.name, len(pm.vertices), len(pm.faces), has_vertex_normals=True, has_vertex_texcoords=True,
                   props=props)
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.ascontiguousarray(pm.vertices, dtype=np.float32).ravel()
    params["vertex_normals"] = np.ascontiguousarray(pm.normals, dtype=np.float32).ravel()
    params["vertex_texcoords"] = mitsuba_texcoords(pm.uvs).ravel()
    params["faces"] = np.ascontiguousarray(pm.faces, dtype=np.uint32).ravel()
    params.update()
    return mesh


def render_preview(posed: list, width: int = 256, height: int = 512, spp: int = 16,
                   seed: int = 0, albedo: bool = False, denoise: bool = False) -> np.ndarray:
    """Linear RGB render (H, W, 3) of posed meshes seen from -Y, framed on their bounds (`albedo`: the albedo AOV
    instead of radiance, e.g. as the denoiser's guide). `denoise`: Open Image Denoise over it, guided by the albedo
    AOV at 4 spp (the same seed), clipped at 0: a look at low spp, not a dataset frame."""
    if denoise and not albedo:
        import pyoidn

        img = render_preview(posed, width, height, spp, seed)
        guide = render_preview(posed, width, height, 4, seed, albedo=True)
        return np.clip(pyoidn.denoise(np.ascontiguousarray(img), albedo=np.ascontiguousarray(guide), hdr=True),
                       0.0, None)
    mi = _mi()
    lo, hi = body_bounds(posed)
    centre = 0.5 * (lo + hi)
    fov_y = 30.0
    half = 0.55 * max(hi[2] - lo[2], (hi[0] - lo[0]) * height / width)
    dist = half / np.tan(np.radians(fov_y / 2))
    scene = {
        "type": "scene",
        "integrator": {"type": "aov", "aovs": "a:albedo"} if albedo else {"type": "path", "max_depth": 6},
        "sensor": {
            "type": "perspective",
            "fov": fov_y,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=[float(centre[0]), float(centre[1] - dist), float(centre[2])],
                target=[float(centre[0]), float(centre[1]), float(centre[2])],
                up=[0, 0, 1],
            ),
            "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        },
        # Mitsuba's envmap is +Y up; rotate it so its up is our +Z.
        "light": {"type": "envmap", "filename": str(STUDIO_HDRI),
                  "to_world": mi.ScalarTransform4f().rotate([0, 0, 1], 200).rotate([1, 0, 0], 90)},
    }
    from .strand_shape import mitsuba_curves

    for i, pm in enumerate(posed):
        strands = hasattr(pm, "fibre")
        scene[f"part_{i:02d}_{pm.name}"] = mitsuba_curves(pm, stand_in=albedo) if strands else _mesh(mi, pm)
    img = np.array(mi.render(mi.load_dict(scene)), dtype=np.float32)[..., :3]
    return img


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8, help="number of characters")
    ap.add_argument("--out", type=Path, default=Path("/tmp/chars.png"),
                    help="PNG contact sheet written (default /tmp/chars.png)")
    ap.add_argument("--pool", choices=POOLS, default="benchmark",
                    help="recipe pool the characters are drawn from (default benchmark)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the generator recipes are drawn with")
    ap.add_argument("--spp", type=int, default=16, help="samples per pixel of each 256x512 tile (default 16)")
    ap.add_argument("--cols", type=int, default=4, help="tiles per row of the sheet (default 4)")
    ap.add_argument("--texture-resolution", type=int, default=1024,
                    help="texture resolution of each character (build_character's, 16 to 8192; default 1024)")
    ap.add_argument("--exposure", type=float, default=1.3,
                    help="factor on the linear render before sRGB encoding (default 1.3)")
    ap.add_argument("--denoise", action=argparse.BooleanOptionalAction, default=True,
                    help="denoise each tile with Open Image Denoise (pyoidn) - look-dev only, biased")
    args = ap.parse_args(argv)
    if args.n < 1:
        raise SystemExit("--n must be >= 1")
    rng = np.random.default_rng(args.seed)
    tiles = []
    for i in range(args.n):
        recipe = sample_recipe(rng, args.pool, i)
        t0 = time.perf_counter()
        character = build_character(recipe, args.texture_resolution)
        t1 = time.perf_counter()
        posed = pose_character(character)
        t2 = time.perf_counter()
        img = render_preview(posed, spp=args.spp, seed=i, denoise=args.denoise)
        t3 = time.perf_counter()
        kinds = ",".join(g.kind for g in recipe.garments)
        print(f"[{i}] {recipe.hair.style:8s} melanin={recipe.skin.melanin:.2f} {kinds:40s} "
              f"{character.triangle_count} tris  build {t1 - t0:.2f}s pose {t2 - t1:.2f}s render {t3 - t2:.2f}s")
        tiles.append(quantize8(srgb_encode(img * args.exposure)))
    cols = min(args.cols, len(tiles))
    rows = -(-len(tiles) // cols)
    h, w = tiles[0].shape[:2]
    sheet = np.full((rows * h, cols * w, 3), 255, dtype=np.uint8)
    for k, t in enumerate(tiles):
        r, c = divmod(k, cols)
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = t
    write_png(args.out, sheet)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
