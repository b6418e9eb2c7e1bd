"""What skin and cloth detail the protocol's pixels resolve, and what the detail costs.

    python bench/skin_detail.py                       # footprint over the 49 subjects, costs on subjects 22 41 0
    python bench/skin_detail.py --subjects 22 --no-pores --out /tmp/skin_detail

Prints
1. the pixel footprint: mm of body surface per pixel at 512 x 512, 30 degree vertical fov, camera fill 0.96, for
   each benchmark subject's framing (`rh_dataset.generate.subjects.framing_box` + `frame_body`; here from anny's
   body bounds alone, which leave out the hair and shoes: the built subjects below print the exact framing too), at
   the nearest body point and at the pelvis plane. mm/px = 2 z tan(fov / 2) / H at camera distance z;
2. the skin texture's texel size (1024^2 over anny's UV layout);
3. the detail's cost: skin texture build time with and without freckles, blush and veins, texture memory, and
   seconds per 512 x 512 frame (the draft preset: 12 multijitter spp, depth 3, AOV pass at 4) with the subject's
   drawn detail and fabric sheen against the same subject without either, under Blender's studio HDRI, front view,
   rest pose. The images go to --out (before | after; the face crops at 4x: image above, albedo layer below);
   `--figure docs/skin_detail.png` writes the face crops of every subject in one picture;
4. what detail below the footprint would cost: skin pores as a tangent-space normal map at 2048^2 (0.47 mm texels;
   pores are 0.1-0.3 mm, so this is still coarser than pores): memory, render seconds, and how far it moves the
   image compared with the Monte Carlo noise (PSNR against the no-pores render, and between two seeds of it); and
   the texture size resolving 0.1 mm pores would take.
Timings are medians of --repeats runs after one warm-up; the load average is printed with them.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the bench folder's modules
from subjects_gallery import studio_environment  # noqa: E402

RES, FOV = 512, 30.0


def _mm_per_px(z: float) -> float:
    return 2000.0 * z * math.tan(math.radians(FOV) / 2.0) / RES


def footprint(lo: np.ndarray, hi: np.ndarray, front_y: float) -> tuple[float, float]:
    """(mm/px at the nearest body point, mm/px at the framed box's centre plane) of a subject's protocol camera."""
    from rh_common.camera import frame_body
    from rh_dataset.generate.subjects import CAMERA_FILL, framing_box

    cam = frame_body(*framing_box(lo, hi), RES, RES, FOV, fill=CAMERA_FILL)
    z_centre = float(cam.target[1] - cam.origin[1])
    return _mm_per_px(front_y - cam.origin[1]), _mm_per_px(z_centre)


def body_only_footprints(recipes) -> np.ndarray:
    from rh_dataset.characters.body import run_anny

    out = []
    for r in recipes:
        v = run_anny(r.phenotype)["vertices"]
        out.append(footprint(v.min(0), v.max(0), float(v[:, 1].min())))
    return np.array(out)


def _without_detail(recipe):
    skin = dataclasses.replace(recipe.skin, freckles=0.0, blush=0.0, veins=0.0)
    return dataclasses.replace(recipe, skin=skin, garments=tuple(dataclasses.replace(g, fabric="plain")
                                                                  for g in recipe.garments))


def _timed(fn, repeats: int):
    fn()  # warm-up (JIT kernels)
    ts, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts)), out


def _png(path: Path, img: np.ndarray) -> None:
    from rh_common.colourspace import quantize8, srgb_encode
    from rh_common.imageio import write_png

    write_png(path, quantize8(srgb_encode(np.clip(img, 0.0, None))))


def _pore_normal_map(res: int, seed: int) -> np.ndarray:
    """Tangent-space normals of pores (encoded n * 0.5 + 0.5, float32 (res, res, 3)): slopes of ~0.15 varying over
    ~2 texels."""
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    s = ndimage.gaussian_filter(rng.normal(0.0, 1.0, (2, res, res)).astype(np.float32), (0, 1.0, 1.0))
    s *= 0.15 / max(float(s.std()), 1e-6)
    n = np.stack([s[0], s[1], np.ones((res, res), np.float32)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.ascontiguousarray(n * 0.5 + 0.5, dtype=np.float32)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", type=int, nargs="*", default=[22, 41, 0], help="benchmark subjects to render")
    ap.add_argument("--seed", type=int, default=0, help="dataset seed (rh-generate --seed)")
    ap.add_argument("--spp", type=int, default=12, help="samples per pixel of the renders of parts 3 and 4 "
                    "(default 12)")
    ap.add_argument("--repeats", type=int, default=1,
                    help="timed runs after one warm-up, medians printed (default 1; the texture builds at least 2)")
    ap.add_argument("--out", type=Path, default=Path("/tmp/skin_detail"),
                    help="folder for each subject's PNGs: before | after, albedo, face crops at 4x "
                         "(default /tmp/skin_detail)")
    ap.add_argument("--no-pores", action="store_true", help="skip part 4 (the pore normal map renders)")
    ap.add_argument("--figure", type=Path, help="also write one PNG: a row per subject of its face crops at 4x "
                                                "(image before, after; albedo before, after)")
    args = ap.parse_args()

    from subject_diversity import benchmark_recipes

    from rh_common.camera import frame_body
    from rh_dataset.characters import body_bounds, build_character, pose_character
    from rh_dataset.characters.textures import _mask, skin_texture, texel_positions
    from rh_dataset.characters.body_features import body_features
    from rh_dataset.generate.subjects import CAMERA_FILL, framing_box
    from rh_dataset.render.passes import render_frame
    from rh_dataset.render.scene import RenderSettings
    from rh_dataset.variant import load_mitsuba, select_variant

    recipes = benchmark_recipes("protocol_a", args.seed)
    print(f"load average at start: {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")
    fp = body_only_footprints(recipes)
    print(f"1. pixel footprint over the {len(recipes)} subjects (anny body bounds), mm of surface per pixel:")
    for j, where in enumerate(("nearest body point", "pelvis plane")):
        q = np.quantile(fp[:, j], [0.0, 0.5, 1.0])
        print(f"   {where:18s} min {q[0]:.2f}  median {q[1]:.2f}  max {q[2]:.2f}")
    print(f"   a pattern resolves at >= 1 px features / >= 2 px periods: >= {np.median(fp[:, 0]):.1f} mm features, "
          f">= {2 * np.median(fp[:, 0]):.1f} mm periods")

    feats = body_features(recipes[args.subjects[0] if args.subjects else 0].phenotype)
    pos = texel_positions(feats, 1024)
    d = np.linalg.norm(np.diff(pos, axis=1), axis=-1)
    ok = d < 0.01  # not across an island seam
    face = (_mask("face", 1024)[:, :-1] > 0.5) & ok
    print(f"2. skin texture 1024^2: texel {1000 * np.median(d[ok]):.2f} mm (face {1000 * np.median(d[face]):.2f} mm)")

    r0 = recipes[args.subjects[0] if args.subjects else 0]
    full = dataclasses.replace(r0.skin, freckles=1.0, blush=1.0, veins=1.0)
    plain = dataclasses.replace(r0.skin, freckles=0.0, blush=0.0, veins=0.0)
    t_plain, a = _timed(lambda: skin_texture(plain, r0.hair.colour, feats, np.random.default_rng(1), 1024,
                                             positions=pos), max(args.repeats, 2))
    t_full, _ = _timed(lambda: skin_texture(full, r0.hair.colour, feats, np.random.default_rng(1), 1024,
                                            positions=pos, detail_rng=np.random.default_rng(4)), max(args.repeats, 2))
    print(f"3. skin texture build at 1024^2: {t_plain:.2f} s without detail, {t_full:.2f} s with all three at full "
          f"strength (+{t_full - t_plain:.2f} s per subject, once); texture memory {a.nbytes / 2**20:.0f} MiB either "
          f"way (the detail is baked into the albedo; sheen is one number per garment)")

    if not args.subjects:
        return
    select_variant(None)
    mi = load_mitsuba()
    env = studio_environment(mi)  # the galleries' light (subjects_gallery.py)
    settings = RenderSettings(spp=args.spp, aov_spp=4, max_depth=3, sampler="multijitter")
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"   seconds per {RES}x{RES} frame ({args.spp} spp, depth 3, aov 4; load average "
          f"{os.getloadavg()[0]:.2f}):")
    last, rows_fig = None, []
    for s in args.subjects:
        r = recipes[s]
        imgs, secs = {}, {}
        for label, rec in (("before", _without_detail(r)), ("after", r)):
            posed = pose_character(build_character(rec))
            body = next(m for m in posed if m.name == "body")
            lo, hi = body_bounds(posed)
            cam = frame_body(*framing_box(lo, hi), RES, RES, FOV, fill=CAMERA_FILL)
            t, out = _timed(lambda: render_frame(posed, env, cam, settings, ["image", "albedo", "mask"], seed=s),
                            args.repeats)
            imgs[label], secs[label] = out.layers, t
            last = (posed, cam, body)
        front = float(last[2].vertices[:, 1].min())
        near, centre = footprint(lo, hi, front)
        fabrics = ",".join(f"{g.kind}:{g.fabric}" for g in r.garments if g.fabric != "plain") or "none"
        print(f"   subject {s:2d}: {secs['before']:.1f} s before, {secs['after']:.1f} s after "
              f"(x{secs['after'] / secs['before']:.2f}); freckles {r.skin.freckles:.2f} blush {r.skin.blush:.2f} "
              f"veins {r.skin.veins:.2f}; sheen on {fabrics}; exact footprint {near:.2f} / {centre:.2f} mm/px")
        pair = np.concatenate([imgs["before"]["image"], imgs["after"]["image"]], 1) * 1.3
        _png(args.out / f"subject_{s:02d}.png", pair)
        alb = np.concatenate([imgs["before"]["albedo"], imgs["after"]["albedo"]], 1)
        _png(args.out / f"subject_{s:02d}_albedo.png", alb)
        m = imgs["after"]["mask"]
        rows = np.flatnonzero(m.max(1) > 0.5)
        top = int(rows.min()) if len(rows) else 0
        cols = np.flatnonzero(m[top:top + 40].max(0) > 0.5)
        cx = int(np.median(cols)) if len(cols) else RES // 2
        y0, x0 = max(top - 4, 0), max(cx - 32, 0)
        crop = np.concatenate([np.concatenate([imgs[k]["image"][y0:y0 + 64, x0:x0 + 64] * 1.3,
                                               imgs[k]["albedo"][y0:y0 + 64, x0:x0 + 64]], 0)
                               for k in ("before", "after")], 1)
        _png(args.out / f"subject_{s:02d}_face_x4.png", np.repeat(np.repeat(crop, 4, 0), 4, 1))
        rows_fig.append(np.concatenate([crop[:64], crop[64:]], 1))
    if args.figure is not None:
        fig = np.concatenate(rows_fig, 0)
        _png(args.figure, np.repeat(np.repeat(fig, 4, 0), 4, 1))

    if args.no_pores or last is None:
        return
    posed, cam, body = last
    from rh_dataset.render.scene import mitsuba_bsdf, scene_dict

    nm_res = 2048
    nm = _pore_normal_map(nm_res, 0)

    def scene_with(pores: bool):
        d = scene_dict(posed, env, cam, {"type": "path", "max_depth": 3}, args.spp, pixel_format="rgba",
                       sampler="multijitter")
        if pores:
            key = next(k for k in d if k.endswith("_body"))
            base = mitsuba_bsdf(body.material)
            bsdf = mi.load_dict({"type": "normalmap", "bsdf": base,
                                 "normalmap": {"type": "bitmap", "bitmap": mi.Bitmap(nm), "raw": True}})
            mesh = d[key]
            params = mi.traverse(mesh)
            props = mi.Properties()
            props["bsdf"] = bsdf
            m2 = mi.Mesh("body", mesh.vertex_count(), mesh.face_count(), props, has_vertex_normals=True,
                         has_vertex_texcoords=True)
            p2 = mi.traverse(m2)
            for k in ("vertex_positions", "vertex_normals", "vertex_texcoords", "faces"):
                p2[k] = params[k]
            p2.update()
            d[key] = m2
        return mi.load_dict(d)

    def render(pores: bool, seed: int) -> np.ndarray:
        return np.array(mi.render(scene_with(pores), spp=args.spp, seed=seed), dtype=np.float32)[..., :3]

    t0, a0 = _timed(lambda: render(False, 1), args.repeats)
    t1, a1 = _timed(lambda: render(True, 1), args.repeats)
    b0 = render(False, 2)

    def psnr(x, y):
        from rh_common.colourspace import srgb_encode

        e = np.mean((srgb_encode(np.clip(x * 1.3, 0, 1)) - srgb_encode(np.clip(y * 1.3, 0, 1))) ** 2)
        return 10 * np.log10(1.0 / max(float(e), 1e-12))

    need = int(math.ceil(1024 * 0.95 / 0.05))
    print(f"4. pores as a {nm_res}^2 normal map ({nm.nbytes / 2**20:.0f} MiB float32) on subject {args.subjects[-1]}: "
          f"{t1:.1f} s per frame against {t0:.1f} s (x{t1 / t0:.2f}; load average {os.getloadavg()[0]:.2f}); "
          f"PSNR with vs without pores {psnr(a1, a0):.1f} dB, two seeds without {psnr(b0, a0):.1f} dB")
    print(f"   resolving 0.1 mm pores (2 texels each) needs {need}^2 texels: {need * need * 12 / 2**30:.1f} GiB per "
          f"float32 RGB map, and a pixel ({np.median(fp[:, 0]):.1f} mm) averages ~{(np.median(fp[:, 0]) / 0.2) ** 2:.0f} "
          f"pores: what it sees of them is a rougher specular lobe, which the microfacet roughness already models")


if __name__ == "__main__":
    main()
