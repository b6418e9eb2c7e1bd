"""Eyeballs in anny's eye sockets: a sphere per eye fitted to the lids, rigid with anny's head bone.

In: `BodyFeatures` (rest vertices, the `eye.L` / `eye.R` joints) of one phenotype. Out: `EyeFit` (the left ball's
centre, radius and gaze in anny's bind space; the right one is its mirror image) from `fit_eyes`, and
`eye_geometry` -> `EyeGeometry` (both balls as one triangle mesh with UVs, the `SkinBinding` that moves them
rigidly with the head bone, and the polar angles of iris and pupil that `textures.eye_texture` paints).

anny's head is closed over the eyes: behind the slit between the lids the skin turns inwards into a roughly
spherical pocket (radius 14-15.5 mm) around the eye joint, and each lid ends in a flat margin 3-4 mm deep. Seen
from the joint, rays in the slit leave the head; just outside it they meet the margin's front edge (14-18 mm away),
then the margin itself, nearest (11-15 mm) at its inner edge, where the lid turns back into the pocket
(`socket_rim` finds both edges on 72 azimuths). A ball centred near the joint closes the slit without a visible gap
exactly when it reaches past every inner edge (its surface then runs through the lid margins all round); the lids'
flesh in front of the margins keeps it from showing through them (`lid_penetration` measures what does). So: the
centre keeps the joint's depth and is moved sideways and up/down (a 0.1 mm grid over +-3 mm) to the point nearest
to all inner edges, the radius is the farthest inner edge (seen from the joint and from the centre, on both sides)
plus `SEAL`, and the iris looks straight ahead, tilted down to the middle of the slit. The iris's size is
anatomical (11 mm across, a 3.6 mm pupil), placed on the fitted ball.

Skinning: anny has eye joints (`eye.L`, `eye.R`, children of `head`), but the skin around the eyes is weighted to
`head` (>= 0.9) and follows the head's transform to 0.03 mm, while under anny's local-ref pose the eye joints turn
~2 degrees away from the head when the head turns 35 degrees (the joint's centre stays within 0.04 mm): a ball bound
to them would squint for no reason. So the balls are rigid with the head bone, like caps and glasses.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

from .body_features import BodyFeatures
from .drape import SkinBinding

__all__ = ["EyeFit", "EyeGeometry", "RimLoop", "fit_eyes", "eye_geometry", "socket_rim", "lid_penetration",
           "EYE_BONES", "SEAL", "IRIS_RADIUS", "PUPIL_RADIUS", "MIRROR"]

EYE_BONES = ("eye.L", "eye.R")
SEAL = 0.0003  # the ball reaches this far past the lids' inner edges (into the margins) all round
# Visible iris 11 mm across: the adult range is ~10.7-13 mm (mean 11.8); the lower end because anny's slit is only
# ~20 mm wide (a typical palpebral fissure is 28-30 mm), where an 11.8 mm iris left little white on either side.
IRIS_RADIUS = 0.0055
PUPIL_RADIUS = 0.0018  # a 3.6 mm pupil: indoor / daylight-ish
MIRROR = np.array([-1.0, 1.0, 1.0])  # anny is symmetric about x = 0; the right eye is the left one mirrored
_ESCAPE = 0.02  # a ray from the joint that meets no skin within 20 mm has left through the slit
_N_AZ, _N_THETA, _THETA_MAX, _WINDOW = 72, 90, 89.0, 35  # ray fan: azimuths, polar steps (1 deg), inner-edge window
_SHIFT, _STEP = 0.003, 0.0001  # centre search: +-3 mm sideways and vertically, 0.1 mm steps
# Sphere tessellation: rings evenly spaced in sqrt(polar angle) (dense where the iris is, coarse at the back).
_RINGS, _SEGMENTS = 48, 64


@dataclasses.dataclass(frozen=True)
class RimLoop:
    """The lid rim seen from a centre, per azimuth (`_N_AZ` around the forward axis, from the lateral side
    upwards): `front` (A, 3) the first skin points outside the slit, `inner` (A, 3) the nearest margin points
    (where the lid turns back), `theta_open` (A,) radians, the widest polar angle at which rays leave the head."""

    front: np.ndarray
    inner: np.ndarray
    theta_open: np.ndarray


@dataclasses.dataclass(frozen=True)
class EyeFit:
    """The left eyeball in bind space (the right is its mirror image, `MIRROR`): centre (3,), radius (metres),
    gaze (3,) unit, and the left rim seen from the centre."""

    centre: np.ndarray
    radius: float
    gaze: np.ndarray
    rim: RimLoop


@dataclasses.dataclass(frozen=True)
class EyeGeometry:
    """Both balls in bind space: vertices (V, 3) float64 (left ball first, then the right), faces (F, 3) int32
    (outward), uvs (V, 2) float32 in [0, 1] (the azimuthal layout `textures.eye_texture` paints: the gaze's pole at
    (0.5, 0.5), distance from it 0.5 sqrt(polar angle / pi)), skinning (rigid with the head bone),
    theta_iris / theta_pupil: polar angles (radians) of the iris's and pupil's edges on the fitted ball."""

    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    skinning: SkinBinding
    theta_iris: float
    theta_pupil: float
    fit: EyeFit


def _frame(forward: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    f = forward / np.linalg.norm(forward)
    u = up - (up @ f) * f
    u /= np.linalg.norm(u)
    return f, np.cross(u, f), u  # forward, lateral (+x for the face's -y forward and +z up), up


def socket_rim(body_vertices: np.ndarray, body_faces: np.ndarray, centre: np.ndarray, forward: np.ndarray,
               up: np.ndarray) -> RimLoop:
    """Cast a fan of rays from `centre` (inside an eye socket) around `forward` and read the lid rim off it (see the
    module docstring). Works on any pose: give the posed body, the posed centre and the posed axes."""
    import trimesh

    v = np.asarray(body_vertices, np.float64)
    c = np.asarray(centre, np.float64)
    near = np.linalg.norm(v - c, axis=1) < 0.04
    faces = np.asarray(body_faces)[near[np.asarray(body_faces)].all(axis=1)]  # the socket's neighbourhood only
    f, lat, up_ = _frame(np.asarray(forward, np.float64), np.asarray(up, np.float64))
    az = np.radians(np.arange(_N_AZ) * 360.0 / _N_AZ)
    th = np.radians(np.linspace(0.0, _THETA_MAX, _N_THETA))
    a, t = np.meshgrid(az, th, indexing="ij")
    d = (np.cos(t)[..., None] * f + np.sin(t)[..., None] * (np.cos(a)[..., None] * lat + np.sin(a)[..., None] * up_))
    d = d.reshape(-1, 3)
    o = np.broadcast_to(c, d.shape).copy()
    mesh = trimesh.Trimesh(v, faces, process=False)
    loc, ray, _ = mesh.ray.intersects_location(o, d, multiple_hits=True)
    dist = np.full(len(d), np.inf)
    np.minimum.at(dist, ray, np.linalg.norm(loc - o[ray], axis=1))
    dist = dist.reshape(_N_AZ, _N_THETA)
    d = d.reshape(_N_AZ, _N_THETA, 3)
    wall = dist < _ESCAPE
    if wall[:, 0].any() or not wall.any(axis=1).all():
        raise ValueError("socket_rim: the centre is not behind an open eye slit (the gaze ray meets skin within "
                         "20 mm, or some azimuth never meets a lid); pass an eye joint of anny's rest or posed body")
    j0 = np.argmax(wall, axis=1)  # first polar step that meets the lid, per azimuth
    k = np.arange(_N_AZ)
    window = np.clip(j0[:, None] + np.arange(_WINDOW)[None, :], 0, _N_THETA - 1)
    jm = window[k, np.argmin(dist[k[:, None], window], axis=1)]
    front = c + dist[k, j0][:, None] * d[k, j0]
    inner = c + dist[k, jm][:, None] * d[k, jm]
    return RimLoop(front=front, inner=inner, theta_open=th[np.maximum(j0 - 1, 0)])


@functools.lru_cache(maxsize=16)
def _fit_cached(rest_bytes: bytes, joint: tuple[float, float, float]) -> EyeFit:
    from .body import body_topology

    v = np.frombuffer(rest_bytes, np.float64).reshape(-1, 3)
    faces = body_topology().faces
    j = np.array(joint)
    forward, up = np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0])  # anny faces -Y, +Z up
    rim = socket_rim(v, faces, j, forward, up)
    # Centre: the joint's depth kept, moved within the face plane to the point nearest to all inner edges
    # (minimax over a 0.1 mm grid: deterministic, no optimiser tolerances).
    s = np.arange(-_SHIFT, _SHIFT + _STEP / 2, _STEP)
    dx, dz = np.meshgrid(s, s, indexing="ij")
    cand = j + np.stack([dx.ravel(), np.zeros(dx.size), dz.ravel()], 1)
    far = np.sqrt(((rim.inner[None] - cand[:, None]) ** 2).sum(-1)).max(1)
    centre = cand[int(np.argmin(far))]
    # The rim seen from the chosen centre (the nearest margin point along a ray depends on where the rays start),
    # on both sides (the right centre is the mirror image; anny's mesh is symmetric only to rounding): the ball
    # reaches past every inner edge found from either joint or either centre.
    rims = [rim, socket_rim(v, faces, centre, forward, up), socket_rim(v, faces, centre * MIRROR, forward, up)]
    inner = np.concatenate([rims[0].inner, rims[1].inner, rims[2].inner * MIRROR])
    radius = float(np.linalg.norm(inner - centre, axis=1).max()) + SEAL
    # Gaze: straight ahead, tilted to the slit's vertical middle (the opening's polar angles straight up and down).
    th_up, th_down = rim.theta_open[_N_AZ // 4], rim.theta_open[3 * _N_AZ // 4]
    tilt = 0.5 * (th_up - th_down)
    gaze = np.array([0.0, -np.cos(tilt), np.sin(tilt)])
    for a in (centre, gaze):
        a.setflags(write=False)
    return EyeFit(centre=centre, radius=radius, gaze=gaze, rim=rims[1])


def fit_eyes(feats: BodyFeatures) -> EyeFit:
    """The left eyeball fitted to this phenotype's rest-pose socket (cached per body)."""
    j = feats.bone_heads[EYE_BONES[0]]
    return _fit_cached(np.ascontiguousarray(feats.rest_vertices, np.float64).tobytes(), tuple(float(x) for x in j))


def _sphere(centre: np.ndarray, radius: float, gaze: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A UV sphere whose front pole is the gaze: vertices, faces (outward), uvs (azimuthal layout)."""
    f, lat, up = _frame(gaze, np.array([0.0, 0.0, 1.0]))
    rho = np.arange(1, _RINGS) / _RINGS  # 2 x the texture's distance from its centre, per ring
    theta = np.pi * rho ** 2
    phi = 2.0 * np.pi * np.arange(_SEGMENTS + 1) / _SEGMENTS  # a seam column duplicated: u is continuous per face
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = (np.cos(t)[..., None] * f + np.sin(t)[..., None] * (np.cos(p)[..., None] * lat
                                                                + np.sin(p)[..., None] * up))
    uv = 0.5 + 0.5 * np.stack([rho[:, None] * np.cos(p), rho[:, None] * np.sin(p)], -1)
    verts = np.concatenate([centre + radius * f[None], centre + radius * dirs.reshape(-1, 3),
                            centre - radius * f[None]])
    uvs = np.concatenate([[[0.5, 0.5]], uv.reshape(-1, 2), [[0.5, 0.0]]])  # the back pole: sclera (rim side)
    cols = _SEGMENTS + 1
    ring = lambda i: 1 + i * cols  # noqa: E731 - first vertex of ring i
    faces = [(0, ring(0) + s, ring(0) + s + 1) for s in range(_SEGMENTS)]
    for i in range(_RINGS - 2):
        for s in range(_SEGMENTS):
            a, b = ring(i) + s, ring(i) + s + 1
            c, d = ring(i + 1) + s, ring(i + 1) + s + 1
            faces += [(a, c, b), (b, c, d)]
    back = len(verts) - 1
    faces += [(ring(_RINGS - 2) + s, back, ring(_RINGS - 2) + s + 1) for s in range(_SEGMENTS)]
    faces = np.array(faces, np.int64)
    tri = verts[faces]
    if (np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * (tri[:, 0] - centre)).sum() < 0:
        faces = faces[:, ::-1]
    return verts, faces, uvs


def eye_geometry(feats: BodyFeatures) -> EyeGeometry:
    """Both eyeballs of a phenotype, fitted in the rest pose and bound rigidly to anny's head bone."""
    from .headwear import HEAD_BONE, rigid_binding

    fit = fit_eyes(feats)
    vl, fl, uvl = _sphere(fit.centre, fit.radius, fit.gaze)
    vr = vl * MIRROR
    fr = fl[:, ::-1] + len(vl)  # mirroring flips the winding
    uvr = uvl * np.array([-1.0, 1.0]) + np.array([1.0, 0.0])  # mirrored layout: the iris pattern mirrors too
    skin = rigid_binding(np.concatenate([vl, vr]), HEAD_BONE)
    return EyeGeometry(
        vertices=np.concatenate([vl, vr]), faces=np.concatenate([fl, fr]).astype(np.int32),
        uvs=np.clip(np.concatenate([uvl, uvr]), 0.0, 1.0).astype(np.float32), skinning=skin,
        theta_iris=float(np.arcsin(min(IRIS_RADIUS / fit.radius, 1.0))),
        theta_pupil=float(np.arcsin(min(PUPIL_RADIUS / fit.radius, 1.0))), fit=fit)


def lid_penetration(body_vertices: np.ndarray, body_faces: np.ndarray, centre: np.ndarray,
                    points: np.ndarray) -> np.ndarray:
    """How far (metres, >= 0) each point of a ball centred at `centre` pokes out through the skin: a point outside
    the body whose segment from the centre crosses the skin has gone through a lid (or the socket's wall) and shows
    in front of it; its depth is its distance outside the skin (trimesh closest points). Points seen through the
    slit (no skin between them and the centre), and points inside the flesh, are 0."""
    from .drape import penetration
    from .geometry import first_hit

    v = np.asarray(body_vertices, np.float64)
    c = np.asarray(centre, np.float64)
    p = np.asarray(points, np.float64)
    near = np.linalg.norm(v - c, axis=1) < 0.05
    faces = np.asarray(body_faces)[near[np.asarray(body_faces)].all(axis=1)]
    depth = penetration(v, faces, p)  # > 0 inside the body
    out = np.zeros(len(p))
    outside = np.flatnonzero(depth <= 0.0)
    if len(outside):
        seg = p[outside] - c
        length = np.linalg.norm(seg, axis=1)
        hit = first_hit(v, faces, np.broadcast_to(c, seg.shape).copy(), seg / length[:, None])
        crossed = hit < length - 1e-9
        out[outside[crossed]] = -depth[outside[crossed]]
    return out
