"""Small analytic meshes (spheres, quads) that the render tests light and look at."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class AnalyticMaterial:
    albedo: np.ndarray
    roughness: float = 1.0
    specular: float = 0.0


@dataclass
class AnalyticMesh:
    name: str
    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    material: AnalyticMaterial


def uv_sphere(center=(0.0, 0.0, 0.0), radius=1.0, albedo=(1.0, 1.0, 1.0), n_lat=64, n_lon=128,
              name="sphere", texture=None) -> AnalyticMesh:
    """A UV sphere with exact (analytic) vertex normals and equirectangular UVs, v up."""
    th = np.linspace(0.0, np.pi, n_lat + 1)
    ph = np.linspace(0.0, 2.0 * np.pi, n_lon + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    n = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    uv = np.stack([P / (2 * np.pi), 1.0 - T / np.pi], -1).reshape(-1, 2)
    idx = np.arange((n_lat + 1) * (n_lon + 1)).reshape(n_lat + 1, n_lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    # drop degenerate triangles at the poles
    v = np.asarray(center) + radius * n
    area = np.linalg.norm(np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]), axis=1)
    faces = faces[area > 1e-12]
    tex = texture if texture is not None else np.ones((4, 4, 3), np.float32) * np.asarray(albedo, np.float32)
    return AnalyticMesh(name, v.astype(np.float32), n.astype(np.float32), faces.astype(np.int32),
                    uv.astype(np.float32), AnalyticMaterial(np.asarray(tex, np.float32)))


def quad(corners, albedo_texture, name="quad") -> AnalyticMesh:
    """A two-triangle quad; corners in order bottom-left, bottom-right, top-right, top-left (as seen)."""
    v = np.asarray(corners, np.float32)
    nrm = np.cross(v[1] - v[0], v[3] - v[0])
    nrm = nrm / np.linalg.norm(nrm)
    return AnalyticMesh(name, v, np.tile(nrm, (4, 1)).astype(np.float32), np.array([[0, 1, 2], [0, 2, 3]], np.int32),
                    np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32),
                    AnalyticMaterial(np.asarray(albedo_texture, np.float32)))


def gradient_env() -> dict:
    """An environment map that varies across a frame (a vertical gradient and a bright band), so the pixels around a
    sphere are not trivially constant and their few-sample noise is real (the focused and adaptive passes' tests)."""
    from rh_dataset.variant import load_mitsuba

    mi = load_mitsuba()
    v = np.linspace(0.0, 1.0, 32, dtype=np.float32)[:, None, None]
    img = np.broadcast_to(0.2 + 1.5 * v, (32, 64, 3)).copy()
    img[:, 20:24] = 4.0
    return {"type": "envmap", "bitmap": mi.Bitmap(img)}


@dataclass(frozen=True)
class Strands:
    """Hair strands as the renderer takes them (`rh_dataset.render.scene.StrandsLike`): (S, K, 3) cubic B-spline
    control points and (S, K) radii in metres, and a fibre (`rh_dataset.characters.hair_fibre.HairFibre`)."""
    name: str
    points: np.ndarray
    radius: np.ndarray
    fibre: object


def sphere_camera(n: int = 24):
    """An n x n camera 4 units in front of the unit sphere at the origin."""
    from rh_common.camera import Camera

    return Camera(width=n, height=n, fov_y_deg=50.0, origin=(0.0, -4.0, 0.3), target=(0.0, 0.0, 0.0))


_DEEP_REFERENCE: dict = {}


def deep_sphere_reference():
    """The full-frame reference the unbiasedness tests of the focused and adaptive beauty passes compare against:
    the sphere (albedo 0.6, 0.5, 0.4) under `gradient_env` seen by `sphere_camera`, 16 chunks of 256 independent spp
    at depth 3. Returns (env, camera, meshes, mean image, variance of that mean from its chunks), float64 images.
    Rendered once per test session (a few seconds) and shared."""
    if not _DEEP_REFERENCE:
        from rh_dataset.render.passes import render_frame
        from rh_dataset.render.scene import RenderSettings

        env, cam, sphere = gradient_env(), sphere_camera(), [uv_sphere(albedo=(0.6, 0.5, 0.4))]
        chunks = [render_frame(sphere, env, cam, RenderSettings(spp=256, aov_spp=4, max_depth=3), ["image"],
                               seed=100 + k).layers["image"].astype(np.float64) for k in range(16)]
        _DEEP_REFERENCE["ref"] = (env, cam, sphere, np.mean(chunks, axis=0),
                                  np.var(chunks, axis=0, ddof=1) / len(chunks))
    return _DEEP_REFERENCE["ref"]
