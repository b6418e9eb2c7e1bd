"""Eyebrows and eyelashes as strands, grown on anny's face in the bind pose and bound to the head's skin.

In: `BodyFeatures` of one phenotype (bind-pose vertices, the eye joints) and a random stream. Out: `StrandGeometry`
(hair.py's: S strands x POINTS control points, radii, and each control point's binding, which `pose_character`
anchors as it does the scalp's hair) for both brows (`build_brows`) or both eyes' upper lashes (`build_lashes`);
`character._build_cached` deals them to the scalp hair's fibres, so they share its melanin and its albedo ground
truth (docs/ARCHITECTURE.md, "Hair").

Brows: BROW_HAIRS roots a brow, drawn uniformly over the band `textures.brow_band` places above each eye (the band
the skin texture painted before strands), each laid on the skin by a ray from in front of the face (anny faces -y).
A hair runs along the skin (its control points put back on the skin's closest point, BROW_LIFT off it) in a
direction that turns from steeply up at the brow's medial end to slightly down at the temple (BROW_ANGLE), medial
hairs shorter (BROW_LENGTH).
Lashes: LASH_HAIRS roots an eye along the upper lid's front edge (`eyes.fit_eyes(...).rim.front`, the lid's
azimuths LASH_ARC), each curving forward and up off the lid, longest at the middle of the lid (LASH_LENGTH).
Binding: `geometry.bind_points` over the head's skin, unsmoothed (a hair lies within a millimetre of the skin it
grows from; the head's skin follows the head bone to 0.03 mm, eyes.py).
"""
from __future__ import annotations

import numpy as np

from .body import body_topology
from .body_features import BodyFeatures
from .eyes import MIRROR, fit_eyes
from .geometry import bind_points, closest_point, query_mesh
from .hair import StrandGeometry
from .textures import BROW_SPAN, brow_band

__all__ = ["build_brows", "build_lashes", "BROW_HAIRS", "BROW_RADIUS", "BROW_LENGTH", "BROW_LIFT", "BROW_ANGLE",
           "LASH_HAIRS", "LASH_RADIUS", "LASH_LENGTH", "LASH_ARC", "POINTS"]

POINTS = 4  # control points per hair (a cubic B-spline, as the scalp's)
BROW_HAIRS = 450  # per brow: an adult brow has ~100-200 hairs a square centimetre over ~3 cm²
BROW_RADIUS = 0.00006  # metres at the root (brow hairs are ~0.1 mm thick or more), tapering to 40 % at the tip
BROW_LENGTH = (0.005, 0.011)  # metres: medial hairs short, lateral ones long
BROW_LIFT = (0.00015, 0.0008)  # metres off the skin at the root and at the tip
BROW_ANGLE = (75.0, -20.0)  # degrees above the horizontal at the medial end and at the temple (+-10 jitter)
LASH_HAIRS = 100  # upper lashes per eye (adults have ~90-160)
LASH_RADIUS = 0.00004  # metres at the root, tapering to 40 % at the tip
LASH_LENGTH = (0.005, 0.009)  # metres: at the lid's corners and at its middle
LASH_ARC = (20.0, 160.0)  # degrees of the rim's azimuth (0 lateral, 90 up) the upper lashes grow along


def _taper(radius: float, n: int) -> np.ndarray:
    return (radius * (1.0 - 0.6 * np.linspace(0.0, 1.0, POINTS)))[None, :].repeat(n, 0)


def _bound(kind: str, rest: np.ndarray, radius: np.ndarray, feats: BodyFeatures) -> StrandGeometry:
    b = bind_points(rest.reshape(-1, 3), feats.in_groups("head"), feats, smooth_radius=0.0)
    return StrandGeometry(kind, rest, radius.astype(np.float32), b.blend_vertices.astype(np.int32),
                          b.blend_weights.astype(np.float32), b.offset.astype(np.float32))


def build_brows(feats: BodyFeatures, rng: np.random.Generator) -> StrandGeometry:
    """Both brows' hairs, left brow first (deterministic for a given `rng` state)."""
    mesh = query_mesh(feats.rest_vertices, body_topology().faces)
    hairs = []
    for side, sign in (("L", 1.0), ("R", -1.0)):
        e = np.asarray(feats.bone_heads[f"eye.{side}"], np.float64)
        dx = rng.uniform(*BROW_SPAN, 8 * BROW_HAIRS)
        arch, half = brow_band(dx)
        keep = rng.random(len(dx)) < half / half.max()  # uniform over the band's area (it thins to the temple)
        dx, arch, half = dx[keep][:BROW_HAIRS], arch[keep][:BROW_HAIRS], half[keep][:BROW_HAIRS]
        dz = arch + rng.uniform(-1.0, 1.0, len(dx)) * half
        jitter, share = rng.uniform(-10.0, 10.0, len(dx)), rng.uniform(0.7, 1.0, len(dx))
        origins = np.stack([e[0] + sign * dx, np.full(len(dx), e[1] - 0.2), e[2] + dz], 1)
        ways = np.tile([0.0, 1.0, 0.0], (len(dx), 1))
        loc, ray, tri = mesh.ray.intersects_location(origins, ways, multiple_hits=False)
        if len(ray) != len(dx):
            raise ValueError(f"build_brows: {len(dx) - len(ray)} brow roots found no skin in front of eye.{side}")
        order = np.argsort(ray)  # trimesh returns hits in no fixed order
        loc, ray, tri = loc[order], ray[order], tri[order]
        n = mesh.face_normals[tri]
        u = (dx[ray] - BROW_SPAN[0]) / (BROW_SPAN[1] - BROW_SPAN[0])  # 0 medial .. 1 temple
        a = np.radians(BROW_ANGLE[0] + (BROW_ANGLE[1] - BROW_ANGLE[0]) * u + jitter[ray])
        d = np.stack([sign * np.cos(a), np.zeros(len(a)), np.sin(a)], 1)
        d -= (d * n).sum(1, keepdims=True) * n
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        length = BROW_LENGTH[0] + (BROW_LENGTH[1] - BROW_LENGTH[0]) * u * share[ray]
        s = np.linspace(0.0, 1.0, POINTS)
        p = loc[:, None, :] + (s[None, :, None] * length[:, None, None]) * d[:, None, :]
        on, _, t = closest_point(mesh, p.reshape(-1, 3))  # along the skin's curve
        lift = BROW_LIFT[0] + (BROW_LIFT[1] - BROW_LIFT[0]) * np.tile(s, len(u))
        hairs.append((on + lift[:, None] * mesh.face_normals[t]).reshape(-1, POINTS, 3))
    rest = np.concatenate(hairs)
    return _bound("brows", rest, _taper(BROW_RADIUS, len(rest)), feats)


def build_lashes(feats: BodyFeatures, rng: np.random.Generator) -> StrandGeometry:
    """Both eyes' upper lashes, left eye first (deterministic for a given `rng` state)."""
    fit = fit_eyes(feats)
    rim = fit.rim.front  # (72, 3) around the forward axis from the lateral side, counter-clockwise seen from front
    az = np.radians(np.arange(len(rim)) * 360.0 / len(rim))
    forward = np.array([0.0, -1.0, 0.0])
    hairs = []
    for mirror in (np.ones(3), MIRROR):
        t = np.sort(rng.uniform(*np.radians(LASH_ARC), LASH_HAIRS))
        root = np.stack([np.interp(t, az, rim[:, k]) for k in range(3)], 1)
        mid = np.sin((t - np.radians(LASH_ARC[0])) / np.radians(LASH_ARC[1] - LASH_ARC[0]) * np.pi)  # 0 .. 1 .. 0
        length = (LASH_LENGTH[0] + (LASH_LENGTH[1] - LASH_LENGTH[0]) * mid) * rng.uniform(0.85, 1.0, len(t))
        out = root - fit.centre  # outwards from the ball's centre, through the lid's edge
        out /= np.linalg.norm(out, axis=1, keepdims=True)
        s = np.linspace(0.0, 1.0, POINTS)[None, :, None]
        # Forward off the lid, curling up: the direction turns from `out` towards up along the lash.
        up = np.array([0.0, 0.0, 1.0])
        d0 = out + 0.5 * forward
        d0 /= np.linalg.norm(d0, axis=1, keepdims=True)
        pts = root[:, None, :] + length[:, None, None] * (s * d0[:, None, :] + 0.6 * s ** 2 * up)
        hairs.append(pts * mirror)
    rest = np.concatenate(hairs)
    return _bound("lashes", rest, _taper(LASH_RADIUS, len(rest)), feats)
