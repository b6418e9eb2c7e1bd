"""Tiny synthetic datasets in the ARCHITECTURE.md layout, rendered with our own rasteriser (no Mitsuba).

In: a folder and a few sizes (subjects, frames, resolution, seed). Out: a dataset written through
`rh_common.layout` (the same frame records, layer files and manifest as rh-generate's, so rh-verify accepts it),
plus each subject's `synthetic_truth.pt` (albedo texture and offsets) for tests that know the answer.

For tests and smoke runs while the path-traced generator is not at hand: an anny body with known offsets (a
'garment' shell), a procedural albedo texture, order-2 SH light, Lambertian shading without shadows, 2x2
super-sampled coverage. Because the image formation is exactly RANA's model, a method that recovers geometry,
albedo and light exactly would score perfectly here; the path-traced benchmark is harder.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from rh_common import layout, sh
from rh_common.imageio import write_json

from .body import PosedBody, body_topology, pose_body, vertex_normals
from .raster import interpolate, project, rasterize
from .texture import sample_texture, uv_raster

__all__ = ["make_dataset", "procedural_albedo", "random_sh", "render_lambertian", "sh_background", "DEFAULT_PHENOTYPE"]

DEFAULT_PHENOTYPE = {"gender": 0.5, "age": 0.5, "muscle": 0.5, "weight": 0.5, "height": 0.5, "proportions": 0.5}


def random_sh(rng: np.random.Generator, strength: float = 1.0) -> np.ndarray:
    """(9, 3) radiance coefficients of an ambient term plus a soft coloured lobe (non-negative environment)."""
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    amb = rng.uniform(0.3, 0.7) * rng.uniform(0.8, 1.2, size=3)
    lobe = strength * rng.uniform(0.5, 1.5) * rng.uniform(0.7, 1.3, size=3)
    Y = sh.basis(d)
    # A smooth lobe: Y_i(d) attenuated per band (1, 1/2, 1/8) stays >= 0 over the sphere.
    g = np.array([1.0, 0.5, 0.5, 0.5] + [0.125] * 5)
    c = (Y * g)[:, None] * lobe[None] * (4 * math.pi / 9)
    c[0] += amb * 2 * math.sqrt(math.pi)  # constant radiance amb: L_0 = amb * 4pi * Y_0
    return c


def sh_background(sh_camera: torch.Tensor, K: torch.Tensor, H: int, W: int) -> torch.Tensor:
    """(H, W, 3) radiance of the order-2 environment seen through each pixel (directions in OpenGL camera axes)."""
    v, u = torch.meshgrid(torch.arange(H) + 0.5, torch.arange(W) + 0.5, indexing="ij")
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    d = F.normalize(torch.stack([x, -y, -torch.ones_like(x)], -1), dim=-1)  # OpenCV ray → OpenGL axes
    return (sh.basis(d) @ sh_camera.to(d)).clamp_min(0)


def procedural_albedo(size: int, rng: np.random.Generator, offsets_shell: torch.Tensor | None = None) -> torch.Tensor:
    """(3, S, S) albedo in anny's UV layout: skin, a shirt over the torso and arms, trousers, stripes."""
    topo = body_topology()
    uvr = uv_raster(size)
    rest = pose_body(DEFAULT_PHENOTYPE, {"bones": {}}).posed0
    sel = uvr.valid.reshape(-1)
    tri = uvr.raster.tri.reshape(-1)[sel]
    b = uvr.raster.bary.reshape(-1, 3)[sel]
    p = (b[..., None] * rest[topo.faces[tri]]).sum(1)
    z = p[:, 2]
    lo, hi = rest[:, 2].min(), rest[:, 2].max()
    t = (z - lo) / (hi - lo)
    skin = torch.tensor(rng.uniform([0.45, 0.3, 0.2], [0.75, 0.55, 0.45]), dtype=torch.float32)
    shirt = torch.tensor(rng.uniform(0.1, 0.8, size=3), dtype=torch.float32)
    pants = torch.tensor(rng.uniform(0.05, 0.5, size=3), dtype=torch.float32)
    col = skin.expand(len(p), 3).clone()
    shirt_m = (t > 0.5) & (t < 0.82) & (p[:, 0].abs() < 0.5)
    pants_m = (t > 0.08) & (t <= 0.5)
    freq = rng.uniform(25, 45)
    stripes = (torch.sin(z * freq) > 0.3).float()[:, None] * 0.25
    col[shirt_m] = (shirt * (1 - stripes[shirt_m]) + stripes[shirt_m] * 0.9).clamp(0, 1)
    col[pants_m] = pants
    tex = torch.full((size * size, 3), 0.5)
    tex[sel] = col
    return tex.view(size, size, 3).permute(2, 0, 1).contiguous()


def render_lambertian(body: PosedBody, offsets: torch.Tensor | None, albedo_tex: torch.Tensor, K: torch.Tensor,
                      w2c: torch.Tensor, H: int, W: int, sh_camera: torch.Tensor, ss: int = 2) -> dict:
    """Layers (radiance image, coverage, albedo, OpenGL normals, depth) at H x W, averaged over ss x ss samples."""
    topo = body_topology()
    Ks = K.clone()
    Ks[:2] *= ss
    verts = body.vertices(offsets)
    r = rasterize(project(verts, Ks, w2c), topo.faces, H * ss, W * ss)
    R = torch.as_tensor(np.diag([1.0, -1.0, -1.0]), dtype=torch.float32) @ w2c[:3, :3]
    n = interpolate(r, topo.faces, vertex_normals(verts, topo.faces) @ R.T)
    n = F.normalize(n, dim=-1, eps=1e-12)
    uv = interpolate(r, topo.face_uv, topo.uv)
    alb = sample_texture(albedo_tex, uv).permute(1, 2, 0) * r.mask[..., None]
    shade = sh.shading(sh_camera.to(n), n).clamp_min(0)  # clamped: radiance cannot be negative
    bg = sh_background(sh_camera, Ks, H * ss, W * ss)
    m = r.mask[..., None].float()
    img = alb * shade * m + bg * (1 - m)

    def down(x):
        return F.avg_pool2d(x.permute(2, 0, 1)[None], ss)[0].permute(1, 2, 0)

    cov = down(m)
    nd = down(n * m)
    nd = F.normalize(nd, dim=-1, eps=1e-12) * (cov > 0)
    ad = down(alb * m) / cov.clamp_min(1e-6)
    dd = down(r.depth[..., None] * m) / cov.clamp_min(1e-6)
    return {"image": down(img), "mask": cov[..., 0], "albedo": ad * (cov > 0), "normal": nd, "depth": dd[..., 0]}


def _frame_camera(H: int, W: int, fov_y_deg: float = 30.0):
    from rh_common.camera import frame_body

    rest = pose_body(DEFAULT_PHENOTYPE, {"bones": {}}).posed0.numpy()
    lo, hi = rest.min(0), rest.max(0)
    h = hi[2] - lo[2]
    return frame_body(lo - [0.1 * h, 0.1 * h, 0], hi + [0.1 * h, 0.1 * h, 0.05 * h], W, H, fov_y_deg, fill=0.92)


def _rot_z(deg: float) -> np.ndarray:
    a = math.radians(deg)
    M = np.eye(4)
    M[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    return M


def _random_pose(rng: np.random.Generator, labels: list[str], amount: float) -> dict:
    bones = {}
    for lab in ("upperarm01.L", "upperarm01.R", "lowerarm01.L", "lowerarm01.R", "upperleg01.L", "upperleg01.R",
                "spine02", "neck01"):
        if lab not in labels:
            continue
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        ang = rng.uniform(-amount, amount)
        Kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        Rm = np.eye(3) + math.sin(ang) * Kx + (1 - math.cos(ang)) * Kx @ Kx
        M = np.eye(4)
        M[:3, :3] = Rm
        bones[lab] = M
    return bones


def make_dataset(out: str | Path, *, subjects: int = 1, train_frames: int = 8, test_frames: int = 3,
                 resolution: int = 64, protocol: str = "a", seed: int = 0, texture_size: int = 128,
                 shell_m: float = 0.012, pool: str = "benchmark", aov_only_train: bool = False) -> Path:
    """Write a small dataset; returns its root. `aov_only_train` makes pretraining-style train frames
    (albedo, normal, mask; no image), like the generator does for rh_dataset/scenes/rana_pretrain.json."""
    from rh_common.body_model import load_anny

    out = Path(out)
    rng = np.random.default_rng(seed)
    labels = list(load_anny().bone_labels)
    topo = body_topology()
    H = W = resolution
    cam = _frame_camera(H, W)
    K = torch.as_tensor(cam.K, dtype=torch.float32)
    w2c = torch.as_tensor(cam.world_to_camera, dtype=torch.float32)
    R_gl = cam.world_to_opengl_rotation()
    # The 'garment': a smooth shell along the rest-pose normals, thicker on the torso.
    rest = pose_body(DEFAULT_PHENOTYPE, {"bones": {}}).posed0
    rn = vertex_normals(rest, topo.faces)
    subj_names = []
    for s in range(subjects):
        name = layout.subject_name(s)
        subj_names.append(name)
        ph = {k: float(np.clip(0.5 + rng.normal(0, 0.1), 0, 1)) for k in DEFAULT_PHENOTYPE}
        offsets = rn * shell_m
        tex = procedural_albedo(texture_size, rng)
        write_json(out / name / layout.CHARACTER_JSON, {"format": "rana-synthetic/1", "phenotype": ph, "seed": seed})
        torch.save({"albedo_texture": tex, "offsets": offsets}, out / name / "synthetic_truth.pt")
        train_sh = random_sh(rng)
        splits = {"train": train_frames, "test": test_frames}
        for split, n in splits.items():
            d = layout.split_dir(out, name, protocol, split)
            for i in range(n):
                if split == "train":
                    pose = {"parameterization": "local-ref", "bones": {},
                            "root_transform": _rot_z(360.0 * i / n) if not aov_only_train else _rot_z(rng.uniform(0, 360))}
                    if aov_only_train:
                        pose["bones"] = _random_pose(rng, labels, 0.6)
                    sh_world = train_sh
                    layers = ("albedo", "normal", "mask") if aov_only_train else ("image", "mask")
                else:
                    pose = {"parameterization": "local-ref", "bones": _random_pose(rng, labels, 0.6),
                            "root_transform": _rot_z(rng.uniform(-60, 60))}
                    sh_world = random_sh(rng)
                    layers = ("image", "mask", "albedo", "normal", "depth")
                sh_cam = sh.rotate(sh_world, R_gl)
                pose_json = {k: (np.asarray(v).tolist() if k != "bones" else
                                 {b: np.asarray(m).tolist() for b, m in v.items()}) for k, v in pose.items()}
                pb = pose_body(ph, pose_json)
                L = render_lambertian(pb, offsets, tex, K, w2c, H, W, torch.as_tensor(sh_cam, dtype=torch.float32))
                mean_rad = float(sh_world[0] @ np.array([0.2126, 0.7152, 0.0722])) / (4 * math.pi * sh.SH_CONSTANTS[0])
                exposure = 1.0 / max(mean_rad, 1e-6)
                meta = {
                    "subject": name, "protocol": protocol, "split": split, "width": W, "height": H,
                    "camera": {"K": cam.K, "world_to_camera": cam.world_to_camera,
                               "camera_to_world": cam.camera_to_world, "fov_y_deg": cam.fov_y_deg},
                    "body": {"model": "anny", "phenotype": ph, "pose": pose_json, "turntable_deg": 0.0},
                    "light": {"kind": "sh", "name": "synthetic", "source": "", "rotation_deg": 0.0, "scale": 1.0,
                              "sun_azimuth_deg": None, "sun_elevation_deg": None, "turbidity": None,
                              "sh_world": sh_world, "sh_camera": sh_cam, "negative_pixels_clamped": 0},
                    "exposure": exposure,
                    "render": {"variant": "rana-synthetic", "spp": 4, "aov_spp": 4, "max_depth": 1, "seed": seed,
                               "denoised": False, "preset": "synthetic"},
                    "versions": {"rh": "synthetic"},
                }
                # The generator's own writer: the same files, frame record and checksums rh-verify checks.
                layout.write_frame(d, i, {layer: L[layer].numpy() for layer in layers}, meta)
    write_json(out / layout.DATASET_JSON, {"format": "rh-dataset/1", "generator": "rana.synthetic",
                                           "subjects": subj_names, "character_pool": pool, "seed": seed})
    layout.write_manifest(out)
    return out
