"""Glasses frames fitted to anny's face in the rest pose: rims in front of the eyes, a bridge and nose pads on the
nose, temples over the ears that bend down behind them.

In: `BodyFeatures` (rest vertices, the eye bones, the ear mask). Out: (vertices (V, 3), faces (F, 3), uvs (V, 2)) of
the frame as capped tubes (`geometry.closed_tube`), left side designed and mirrored (the frame is exactly
symmetric about x = 0 before `headwear.build_headwear` moves it clear of the skin).

Where the face is comes from trimesh queries against the rest-pose body: the rims start 12 mm in front of the eye
bones and move forward until they clear brow, cheeks and nose (closest points); the bridge arches over the nose's
front (a ray along +Y), the temples follow the side of the head (rays along -X from outside) over the top of the ear
and down behind it, and the pads reach the closest points of the nose's sides. Sizes are a typical adult frame's: 48 x 34 mm
lenses, an 18 mm bridge, 12 mm from the eye's surface to the lens plane, 8 degrees of pantoscopic tilt.
"""
from __future__ import annotations

import numpy as np

from .body import body_topology
from .body_features import BodyFeatures
from .geometry import closed_tube, first_hit

__all__ = ["glasses_frame", "LENS_HALF", "VERTEX_DISTANCE", "RIM_RADIUS"]

LENS_HALF = (0.024, 0.017)  # half width, half height (metres)
VERTEX_DISTANCE = 0.012  # eye surface to lens plane
RIM_RADIUS, TEMPLE_RADIUS, PAD_RADIUS = 0.0018, 0.0015, 0.0012
CLEAR = 0.004  # tube surface above the skin where the frame is designed to rest
_SIDES = 8


def _tube(path: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A capped tube of `_SIDES` sides along an (N, 3) path (frames by parallel transport)."""
    t = np.gradient(path, axis=0)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    ref = np.array([0.0, 0.0, 1.0]) if abs(t[0, 2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    n = np.cross(t[0], ref)
    n /= np.linalg.norm(n)
    ns = []
    for k in range(len(path)):
        n = n - (n @ t[k]) * t[k]
        n /= np.linalg.norm(n)
        ns.append(n)
    ns = np.array(ns)
    bs = np.cross(t, ns)
    a = 2 * np.pi * np.arange(_SIDES) / _SIDES
    rings = path[:, None] + radius * (np.cos(a)[None, :, None] * ns[:, None] + np.sin(a)[None, :, None] * bs[:, None])
    v, f = closed_tube(rings, path[0] - 0.5 * radius * t[0], path[-1] + 0.5 * radius * t[-1])
    tri = v[f]
    if (np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * tri[:, 0]).sum() < 0:  # wind outwards
        f = f[:, ::-1]
    rows, cols = len(path) + 2, _SIDES + 1
    uu, vv = np.meshgrid(np.arange(cols) / _SIDES, np.arange(rows) / (rows - 1))
    return v, f, np.stack([uu.ravel(), vv.ravel()], 1)


def _rotate(p: np.ndarray, centre: np.ndarray, axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    q = p - centre
    out = q.copy()
    out[:, i] = c * q[:, i] - s * q[:, j]
    out[:, j] = s * q[:, i] + c * q[:, j]
    return out + centre


def _left_side(feats: BodyFeatures) -> list[tuple[np.ndarray, float]]:
    """Paths and radii of the left half (x > 0): rim, half the bridge, nose pad, temple."""
    from .drape import closest_on_surface

    v = feats.rest_vertices
    faces = body_topology().faces
    eye = 0.5 * (feats.bone_heads["eye.L"] + feats.bone_heads["eye.R"] * np.array([-1.0, 1.0, 1.0]))
    a, b = LENS_HALF
    centre = np.array([eye[0] + 0.004, eye[1] - VERTEX_DISTANCE, eye[2] - 0.002])
    # The rim: a superellipse (squarish lens) in the x-z plane, tilted 8 degrees (bottom towards the face) and
    # wrapped 6 degrees (the outer edge further back).
    t = np.linspace(0.0, 2 * np.pi, 49)
    x = a * np.sign(np.cos(t)) * np.abs(np.cos(t)) ** 0.7
    z = b * np.sign(np.sin(t)) * np.abs(np.sin(t)) ** 0.7
    rim = centre + np.stack([x, np.zeros_like(t), z], 1)
    rim = _rotate(rim, centre, 0, np.radians(-8.0))
    rim = _rotate(rim, centre, 2, np.radians(-6.0))
    # Forward until the whole rim clears brow, cheeks and the sides of the nose (trimesh closest points).
    for _ in range(8):
        depth = closest_on_surface(v, faces, rim, feats.rest_normals)[0]
        need = float((RIM_RADIUS + CLEAR) + depth.max())
        if need <= 0.0:
            break
        shift = np.array([0.0, -(need + 0.0005), 0.0])
        rim, centre = rim + shift, centre + shift
    paths = [(rim, RIM_RADIUS)]
    # The bridge: from the rim's inner top to x = 0, arching up and forward over the nose (ray cast along +Y).
    inner = rim[np.argmin(np.where(rim[:, 2] > centre[2] + 0.3 * b, rim[:, 0], np.inf))]
    z_mid = inner[2] + 0.005
    far = -0.5
    y_nose = far + first_hit(v, faces, np.array([[0.0, far, z_mid]]), np.array([0.0, 1.0, 0.0]))[0]
    y_mid = min(inner[1], y_nose - RIM_RADIUS - CLEAR)
    s = np.linspace(0.0, 1.0, 10)
    ease = np.sin(0.5 * np.pi * s)
    bridge = np.stack([inner[0] * (1 - s), inner[1] + (y_mid - inner[1]) * ease,
                       inner[2] + (z_mid - inner[2]) * ease], 1)
    paths.append((bridge, RIM_RADIUS))
    # A nose pad: from the rim's inner lower edge to the side of the nose.
    low = rim[np.argmin(np.where(rim[:, 2] < centre[2] - 0.1 * b, rim[:, 0], np.inf))]
    start = low + np.array([0.0, 0.002, 0.0])
    _, q, n = closest_on_surface(v, faces, start[None], feats.rest_normals)
    end = q[0] + (PAD_RADIUS + CLEAR) * n[0]
    if np.linalg.norm(end - start) > 0.002:
        paths.append((start + np.linspace(0.0, 1.0, 4)[:, None] * (end - start), PAD_RADIUS))
    # The temple: from the hinge at the rim's outer edge back over the ear, then down behind it.
    hinge = rim[np.argmax(np.where(rim[:, 2] > centre[2], rim[:, 0], -np.inf))] + np.array([0.002, 0.001, 0.0])
    ear = (feats.masks["ears"] > 0.5) & (v[:, 0] > 0)
    ear_top = v[ear][np.argmax(v[ear, 2])]
    y_back = float(v[ear, 1].max())
    z_over = ear_top[2] + TEMPLE_RADIUS + CLEAR
    ys = np.linspace(hinge[1], y_back + 0.004, 22)
    zs = np.interp(ys, [hinge[1], ear_top[1], y_back + 0.004], [hinge[2], z_over, z_over])
    drop = np.linspace(0.0, 1.0, 8)[1:]
    ys = np.concatenate([ys, y_back + 0.004 + 0.008 * drop])
    zs = np.concatenate([zs, z_over - 0.028 * drop ** 1.3])
    origin = np.stack([np.full(len(ys), 0.3), ys, zs], 1)
    x_side = 0.3 - first_hit(v, faces, origin, np.array([-1.0, 0.0, 0.0]))
    x_side = np.where(np.isfinite(x_side), x_side, hinge[0])
    x = np.maximum(hinge[0] + np.zeros(len(ys)), x_side + TEMPLE_RADIUS + CLEAR)
    temple = np.stack([x, ys, zs], 1)
    temple = np.concatenate([hinge[None], temple[1:]])
    paths.append((temple, TEMPLE_RADIUS))
    return paths


def glasses_frame(feats: BodyFeatures) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The frame's mesh, symmetric about x = 0 (left half designed, then mirrored)."""
    verts, faces, uvs = [], [], []
    for path, radius in _left_side(feats):
        for mirror in (1.0, -1.0):
            v, f, uv = _tube(path * np.array([mirror, 1.0, 1.0]), radius)
            faces.append((f if mirror > 0 else f[:, ::-1]) + sum(len(x) for x in verts))
            verts.append(v)
            uvs.append(uv)
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(uvs)
