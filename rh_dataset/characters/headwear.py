"""Headwear fitted to anny's head in the rest pose: caps, brimmed hats, head scarves (hijab) and glasses frames.

In: the recipe's `Headwear` items, `BodyFeatures`, the phenotype, the outermost garment offset per body vertex.
Out: one `HeadwearGeometry` per item - a triangle mesh in the rest pose with its own UV layout, the
`SkinBinding` that moves it per frame, and what it does to the hair (`HairCover`); `press_hair` applies the
covers to grown strands before they are bound to the body.

Shapes (head frame of `scalp.py`: azimuth from the front towards the character's left, elevation from the plane
through the skull centre; the skull radius is the kernel-regressed one hair grows on):
- cap: a crown `CAP_GAP` above the skull from a band line (forehead, above the ears, occiput) to the top, its edge
  turned under; a visor 4 mm thick reaching 7 cm forward, arched and tilted down. Rigid with the head bone.
- brimmed_hat: a surface of revolution about the head's vertical axis, per azimuth through the band (the skull's
  widest horizontal radius above the band plus `HAT_GAP`), a 7.5 cm brim 5 mm thick drooping at the front and back,
  a tapered crown 3 cm above the skull with a creased top, and the underside closing onto the skull. Rigid.
- headscarf: fabric falling from the crown over head, ears, neck and shoulders outside `scalp.hang_envelope`
  (so it clears head, neck, trunk, upper arms and clothes by `SCARF_GAP`), an oval opening for the face whose
  edge is pulled onto the skin, wrapping under the chin. Skinned with the body's weights (`drape.bind_to_skeleton`), so it bends
  with neck and shoulders.
- glasses: frames as tubes (`glasses.py`), rigid with the head.
Every vertex is then moved `FIT_CLEARANCE` clear of the rest-pose body (trimesh closest points, `drape.push_out`);
posed frames apply `drape.push_out` again, as for draped cloth.

Hair: a cap or a hat presses the hair under it (the height of every control point above the skull where the crown
covers it is compressed to below the crown, easing back over 2.5 cm below the band) and drops strands lying under
it entirely (they cannot be seen); a headscarf hides all hair (no strands are grown).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy import ndimage

from .body_features import BodyFeatures
from .drape import SkinBinding, bind_to_skeleton, push_out
from .geometry import drop_unreferenced, smoothstep
from .recipe import Headwear
from .scalp import Scalp, directions, hang_envelope, sample_envelope, scalp

__all__ = ["HairCover", "HeadwearGeometry", "build_headwear", "press_hair", "rigid_binding", "covered", "depth_under",
           "CAP_GAP", "HAT_GAP", "SCARF_GAP", "FIT_CLEARANCE", "HEAD_BONE"]

CAP_GAP = 0.008  # metres between the skull and a cap's crown (the pressed hair lies in it)
HAT_GAP = 0.008  # between the skull's widest radius above the band and a hat's band
SCARF_GAP = 0.012  # a head scarf's clearance over head, neck, shoulders and clothes
FIT_CLEARANCE = 0.0035  # every headwear vertex this far off the rest-pose skin (above drape.PUSH_CLEARANCE)
HAIR_MARGIN = 0.0025  # pressed hair stays this far under the crown
HEAD_BONE = "head"
_NT = 96  # columns around the head


@dataclasses.dataclass(frozen=True)
class HairCover:
    """What a piece does to the hair: `hides_all` (no hair), or a crown that covers directions above the band
    elevation `band` (per azimuth -180 + 360 k / len(band) degrees) with `room` metres of height above the skull."""

    hides_all: bool
    band: np.ndarray | None = None
    room: float = 0.0


@dataclasses.dataclass(frozen=True)
class HeadwearGeometry:
    """A rest-pose mesh: vertices (V, 3) float64, faces (F, 3) int32 (outward), uvs (V, 2) float32 in [0, 1],
    metres_per_uv (texture scale), skinning (how it follows the pose), cover (what it does to the hair)."""

    kind: str
    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    metres_per_uv: float
    skinning: SkinBinding
    cover: HairCover | None


def _thetas(n: int = _NT) -> np.ndarray:
    return np.radians(-180.0 + 360.0 * np.arange(n) / n)


def _elevation_at_height(sc: Scalp, theta: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Elevation at which the skull surface reaches height z, per azimuth (fixed point on the skull radius)."""
    e = np.zeros_like(theta)
    for _ in range(8):
        e = np.arcsin(np.clip((z - sc.centre[2]) / sc.radius_at(theta, e), -0.99, 0.99))
    return e


def _band_height(kind: str, z_eye: float, theta: np.ndarray) -> np.ndarray:
    """Where the band sits, metres: above the brows at the front, above the ears at the sides, the occiput behind."""
    knots = [0.0, 50.0, 90.0, 135.0, 180.0]
    rel = {"cap": [0.030, 0.028, 0.021, 0.004, -0.008], "brimmed_hat": [0.044, 0.042, 0.034, 0.022, 0.018]}[kind]
    return z_eye + np.interp(np.abs(np.degrees(theta)), knots, rel)


def _outward(vertices: np.ndarray, faces: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Faces wound so their normals point away from `centre` on the whole (signed-volume test)."""
    tri = vertices[faces] - centre
    vol = float((np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * tri[:, 0]).sum())
    return faces if vol >= 0 else faces[:, ::-1]


def _grid_faces(rows: int, cols: int, wrap_cols: bool = False) -> np.ndarray:
    """Quads of a rows x cols vertex grid (row-major) as triangles; wrap_cols joins the last column to the first."""
    i, j = np.meshgrid(np.arange(rows - 1), np.arange(cols if wrap_cols else cols - 1), indexing="ij")
    a = i * cols + j
    b = i * cols + (j + 1) % cols
    c, d = a + cols, b + cols
    return np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])


def _with_pole(grid: np.ndarray, pole: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A (rows, cols, 3) grid (columns around, the last column a seam copy of the first) closed by a pole point
    after its last row. Returns vertices and faces."""
    rows, cols, _ = grid.shape
    faces = _grid_faces(rows, cols)
    p = rows * cols
    last = (rows - 1) * cols + np.arange(cols - 1)
    fan = np.stack([last, np.full(cols - 1, p), last + 1], 1)
    return np.concatenate([grid.reshape(-1, 3), pole[None]]), np.concatenate([faces, fan])


def _grid_uvs(rows: int, cols: int, extra: int = 0) -> np.ndarray:
    u, v = np.meshgrid(np.arange(cols) / (cols - 1), np.arange(rows) / max(rows - 1, 1))
    uv = np.stack([u.ravel(), v.ravel()], 1)
    return np.concatenate([uv, np.tile([[0.5, 1.0]], (extra, 1))]).astype(np.float32)


def _cap(feats: BodyFeatures, sc: Scalp):
    th = np.concatenate([_thetas(), [np.pi]])  # seam column
    e_b = _elevation_at_height(sc, th, _band_height("cap", sc.z_eye, th))
    m = 18
    t = np.linspace(0.0, 1.0, m, endpoint=False)
    ee = e_b[None, :] + (np.pi / 2 - e_b[None, :]) * t[:, None]
    tt = np.broadcast_to(th[None, :], ee.shape)
    gap = CAP_GAP + 0.004 * smoothstep(2.0 * t)[:, None]  # roomier towards the top
    r = sc.radius_at(tt, ee) + gap
    crown = sc.centre + r[..., None] * directions(tt, ee)
    # The edge turned under: a row 3 mm inside the crown, 4 mm up.
    r0 = sc.radius_at(th, e_b)
    e_in = e_b + 0.004 / r0
    inner = sc.centre + (sc.radius_at(th, e_in) + CAP_GAP - 0.003)[:, None] * directions(th, e_in)
    grid = np.concatenate([inner[None], crown], 0)
    r_top = float(sc.radius_at(np.array(0.0), np.array(np.pi / 2)))
    top = sc.centre + (r_top + CAP_GAP + 0.004) * np.array([0.0, 0.0, 1.0])
    v_crown, f_crown = _with_pole(grid, top)
    uv_crown = _grid_uvs(*grid.shape[:2], extra=1)
    # Visor: cross-section loops (top sheet out, bottom sheet back) across azimuths within +-62 degrees.
    tv = np.radians(np.linspace(-62.0, 62.0, 31))
    ev = _elevation_at_height(sc, tv, _band_height("cap", sc.z_eye, tv))
    base = sc.centre + (sc.radius_at(tv, ev) + CAP_GAP - 0.001)[:, None] * directions(tv, ev)
    q = tv / np.radians(62.0)
    length = np.maximum(0.072 * np.sqrt(np.clip(1.0 - q ** 2, 0.0, 1.0)), 0.006)
    h = np.stack([np.sin(tv), -np.cos(tv), np.zeros_like(tv)], 1)
    tilt = np.radians(12.0)
    s = np.linspace(0.0, 1.0, 9)
    top_sheet = (base[:, None] + (s[None, :] * length[:, None])[..., None] * (np.cos(tilt) * h[:, None]
                 - np.sin(tilt) * np.array([0, 0, 1.0])) - (0.016 * q[:, None] ** 2 * s[None, :])[..., None]
                 * np.array([0, 0, 1.0]))
    bottom = top_sheet - 0.004 * np.array([0, 0, 1.0])
    loop = np.concatenate([top_sheet, bottom[:, ::-1]], 1)  # (31, 18, 3)
    v_visor = loop.reshape(-1, 3)
    f_visor = _grid_faces(len(tv), loop.shape[1])
    uv_visor = _grid_uvs(len(tv), loop.shape[1])
    # The visor is not a closed body about the skull centre: wind it so its top sheet faces up.
    n_f = np.cross(v_visor[f_visor[:, 1]] - v_visor[f_visor[:, 0]], v_visor[f_visor[:, 2]] - v_visor[f_visor[:, 0]])
    top_faces = np.all(f_visor % loop.shape[1] < len(s), axis=1)
    if n_f[top_faces, 2].sum() < 0:
        f_visor = f_visor[:, ::-1]
    f_crown = _outward(v_crown, f_crown, sc.centre)
    verts = np.concatenate([v_crown, v_visor])
    faces = np.concatenate([f_crown, f_visor + len(v_crown)])
    uvs = np.concatenate([uv_crown, uv_visor])
    band = _elevation_at_height(sc, _thetas(), _band_height("cap", sc.z_eye, _thetas()))
    return verts, faces, uvs, 0.6, HairCover(False, band, CAP_GAP - HAIR_MARGIN)


def _hat(feats: BodyFeatures, sc: Scalp):
    th = np.concatenate([_thetas(), [np.pi]])
    z_b = _band_height("brimmed_hat", sc.z_eye, th)
    e_b = _elevation_at_height(sc, th, z_b)
    c = sc.centre
    # The skull's widest horizontal radius above the band, per azimuth (the band must pass over it).
    ee = e_b[None, :] + (np.pi / 2 - e_b[None, :]) * np.linspace(0.0, 1.0, 24)[:, None]
    rr = sc.radius_at(np.broadcast_to(th, ee.shape), ee)
    rho_b = (rr * np.cos(ee)).max(0) + HAT_GAP
    rho_s = sc.radius_at(th, e_b) * np.cos(e_b) + FIT_CLEARANCE + 0.001  # the underside closes onto the skull
    z_top = c[2] + float(sc.radius_at(np.array(0.0), np.array(np.pi / 2))) + 0.03
    width, thick = 0.075, 0.005
    droop = 0.004 + 0.010 * np.cos(th) ** 2  # the brim bends down at the front and back
    f = np.linspace(0.0, 1.0, 7)
    prof_rho, prof_z = [], []  # per profile row: (cols,) arrays
    for a in np.linspace(0.0, 1.0, 4)[:-1]:  # underside from the skull to the band
        prof_rho.append(rho_s + a * (rho_b - rho_s)), prof_z.append(z_b - thick + 0 * th)
    for a in f:  # underside out to the edge
        prof_rho.append(rho_b + a * width), prof_z.append(z_b - thick - droop * a ** 2)
    prof_rho.append(rho_b + width + 0.002), prof_z.append(z_b - 0.5 * thick - droop)
    for a in f[::-1]:  # top of the brim back in
        prof_rho.append(rho_b + a * width), prof_z.append(z_b - droop * a ** 2)
    z_wall = z_top - 0.014
    for a in np.linspace(0.0, 1.0, 8)[1:]:  # the crown's wall, tapering
        prof_rho.append(rho_b * (1.0 - 0.07 * a)), prof_z.append(z_b + a * (z_wall - z_b))
    for a, zz in ((0.85, z_top - 0.004), (0.65, z_top), (0.42, z_top - 0.003), (0.2, z_top - 0.008)):
        prof_rho.append(rho_b * a), prof_z.append(zz + 0 * th)  # a rounded top with a crease along the middle
    rho, z = np.array(prof_rho), np.array(prof_z)
    crease = 0.006 * np.cos(th) ** 2 * (rho < 0.5 * rho_b)  # the crease dips most front to back
    z = z - crease
    grid = np.stack([c[0] + rho * np.sin(th), c[1] - rho * np.cos(th), z], -1)
    verts, faces = _with_pole(grid, np.array([c[0], c[1], z_top - 0.012]))
    faces = _outward(verts, faces, c)
    uvs = _grid_uvs(*grid.shape[:2], extra=1)
    band = _elevation_at_height(sc, _thetas(), _band_height("brimmed_hat", sc.z_eye, _thetas()))
    return verts, faces, uvs, 0.8, HairCover(False, band, HAT_GAP - HAIR_MARGIN)


def _scarf(feats: BodyFeatures, sc: Scalp, under: np.ndarray):
    from .drape import closest_on_surface

    c, z_eye = sc.centre, sc.z_eye
    v = feats.rest_vertices
    head = feats.in_groups("head")
    z_top = float(v[head, 2].max()) + SCARF_GAP
    z_sh = 0.5 * float(feats.bone_heads["shoulder01.L"][2] + feats.bone_heads["shoulder01.R"][2])
    th = np.concatenate([_thetas(120), [np.pi]])
    hem = z_sh - 0.075 + 0.045 * np.sin(th) ** 2  # shorter over the shoulders, where the arms begin
    env, zs = hang_envelope(feats, under, float(hem.min()) - 0.02, z_top + 0.01, clear=SCARF_GAP, dz=0.004, lead=1,
                            arms=True)
    rows = 72
    rr, zz = np.empty((rows, len(th))), np.empty((rows, len(th)))
    az = np.degrees(th) % 360.0
    face = head & (feats.masks["face"] > 0.5)
    z_split = float(v[face, 2].min()) - 0.01  # below the chin: rows at common heights (no sheared triangles)
    n_top = 44
    for k in range(len(th)):  # each azimuth's profile from the crown down, evenly in arc length to z_split
        z = np.arange(z_top, z_split, -0.001)
        rho = sample_envelope(env, zs, np.full(len(z), az[k]), z)
        rho[0] = 0.004
        s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(rho), np.diff(z)))])
        u = np.linspace(0.0, s[-1], n_top)
        zb = np.linspace(z_split, hem[k], rows - n_top + 1)[1:]
        rr[:, k] = np.concatenate([np.interp(u, s, rho), sample_envelope(env, zs, np.full(len(zb), az[k]), zb)])
        zz[:, k] = np.concatenate([np.interp(u, s, z), zb])
    # Fabric does not follow every bump of the envelope: smooth it (never inwards), the seam column kept a copy.
    core = rr[:, :-1]
    core = np.maximum(ndimage.gaussian_filter(core, (2.0, 2.5), mode=("nearest", "wrap")), core)
    core = ndimage.gaussian_filter(core, (0.7, 1.0), mode=("nearest", "wrap"))
    rr = np.concatenate([core, core[:, :1]], 1)
    # The face opening, an oval from under the chin to above the brows: the front column is split in two and every
    # row in that height range spreads its columns apart, so the fabric's edge is a smooth curve at +-half(z).
    z_chin = float(v[face, 2].min()) + 0.012
    z_brow = z_eye + 0.045
    knots = [z_chin, z_chin + 0.01, z_eye - 0.045, z_eye, z_eye + 0.025, z_brow - 0.01, z_brow]
    front = len(th) // 2  # theta = 0
    cols = np.concatenate([np.arange(front + 1), np.arange(front, len(th))])  # the front column twice
    side = np.where(np.arange(len(cols)) <= front, -1.0, 1.0)
    zg = zz[:, cols]
    half = np.radians(np.interp(zg, knots, [0.0, 25.0, 46.0, 62.0, 56.0, 32.0, 0.0], left=0.0, right=0.0))
    t0 = np.abs(th[cols])[None, :]
    tq = side * (half + (np.pi - half) * t0 / np.pi)  # the spread azimuths
    rq = rr[:, cols].copy()
    moved = np.argwhere(half > 0)
    for i, j in moved:  # the envelope radius at the spread azimuth and the same height
        f = (tq[i, j] + np.pi) / (2 * np.pi) * (len(th) - 1)
        k0 = int(np.clip(np.floor(f), 0, len(th) - 2))
        a = f - k0
        r0 = np.interp(zg[i, j], zz[::-1, k0], rr[::-1, k0])
        r1 = np.interp(zg[i, j], zz[::-1, k0 + 1], rr[::-1, k0 + 1])
        rq[i, j] = (1 - a) * r0 + a * r1
    grid = np.stack([c[0] + rq * np.sin(tq), c[1] - rq * np.cos(tq), zg], -1)[::-1]  # hem first, crown last
    verts, faces = _with_pole(grid, np.array([c[0], c[1], z_top + 0.001]))
    uvs = _grid_uvs(rows, len(cols), extra=1)
    col_of = np.concatenate([np.tile(np.arange(len(cols)), rows), [-1]])
    slit = np.isin(col_of[faces], [front, front + 1, -1]).all(1)
    faces = faces[~slit]  # nothing joins the two copies of the front column
    tv = np.degrees(np.concatenate([tq[::-1].ravel(), [0.0]]))
    half = np.degrees(np.concatenate([half[::-1].ravel(), [0.0]]))
    # Pull the fabric round the opening onto the skin (a scarf's edge hugs the face and wraps under the chin).
    d_side = np.radians(np.abs(tv) - half) * 0.09
    d_z = np.maximum.reduce([z_chin - verts[:, 2], verts[:, 2] - z_brow, np.zeros(len(verts))])
    w = smoothstep(1.0 - np.hypot(d_side, d_z) / 0.035) * (np.abs(tv) < 110.0)
    near = np.flatnonzero(w > 0)
    from .body import body_topology

    _, q, n = closest_on_surface(v, body_topology().faces, verts[near], feats.rest_normals)
    from scipy.spatial import cKDTree

    cloth = under[cKDTree(v).query(q)[1]]  # a collar under the edge: stay outside it too
    verts[near] += w[near, None] * (q + (FIT_CLEARANCE + 0.003 + cloth)[:, None] * n - verts[near])
    verts, faces, uvs = drop_unreferenced(verts, faces, uvs)
    faces = _outward(verts, faces, c)
    return verts, faces, uvs, 1.2, HairCover(True)


def rigid_binding(points: np.ndarray, bone: str = HEAD_BONE) -> SkinBinding:
    """Points in anny's bind space (`BodyFeatures.rest_vertices`, where headwear is designed) that move rigidly
    with one bone: all weight on it (`skin_points` then applies that bone's transform)."""
    from .body import body_topology

    j = body_topology().bone_labels.index(bone)
    pts = np.asarray(points, dtype=np.float64)
    return SkinBinding(pts.copy(), np.full((len(pts), 1), j, np.int64), np.ones((len(pts), 1), np.float32))


def build_headwear(items: tuple[Headwear, ...], feats: BodyFeatures, phenotype: dict[str, float],
                   under: np.ndarray) -> list[HeadwearGeometry]:
    """Geometry of every headwear item of a recipe, fitted FIT_CLEARANCE clear of the rest-pose body."""
    from .body import body_topology
    from .glasses import glasses_frame

    sc = scalp("short", feats)
    faces_body = body_topology().faces
    out = []
    for item in items:
        if item.kind == "cap":
            v, f, uv, mpu, cover = _cap(feats, sc)
        elif item.kind == "brimmed_hat":
            v, f, uv, mpu, cover = _hat(feats, sc)
        elif item.kind == "headscarf":
            v, f, uv, mpu, cover = _scarf(feats, sc, under)
        else:
            v, f, uv = glasses_frame(feats)
            mpu, cover = 0.3, None
        v, f, uv = drop_unreferenced(np.asarray(v, np.float64), np.asarray(f, np.int64), np.asarray(uv))
        v = push_out(v, feats.rest_vertices, feats.rest_normals, faces_body, clearance=FIT_CLEARANCE)
        if item.kind == "headscarf":
            skin = bind_to_skeleton(v, phenotype, in_bind_space=True)
        else:
            skin = rigid_binding(v)
        out.append(HeadwearGeometry(item.kind, v, np.asarray(f, np.int32), np.clip(uv, 0, 1).astype(np.float32),
                                    mpu, skin, cover))
    return out


def covered(cover: HairCover, sc: Scalp, points: np.ndarray, margin: float = 0.002) -> np.ndarray:
    """Which rest-pose points (N, 3) lie in directions a crown covers: more than `margin` metres (along the skull)
    above its band (the crown's edge is turned under there)."""
    rel = points - sc.centre
    r = np.linalg.norm(rel, axis=1)
    th = np.arctan2(rel[:, 0], -rel[:, 1])
    el = np.arcsin(np.clip(rel[:, 2] / np.maximum(r, 1e-12), -1, 1))
    n = len(cover.band)
    a = np.mod((np.degrees(th) + 180.0) / (360.0 / n), n)
    band = np.interp(a, np.arange(n + 1), np.concatenate([cover.band, cover.band[:1]]))
    return el >= band + margin / sc.radius_at(th, el)


def press_hair(points: np.ndarray, covers: list[HairCover], sc: Scalp) -> tuple[np.ndarray, np.ndarray]:
    """Strands (S, K, 3) under the covers: heights above the skull where a crown covers them compressed to below
    `room` (h -> room (1 - exp(-h / room)), easing back to the grown height over 2.5 cm below the band), strands
    wholly covered dropped. Returns (points, keep (S,) bool)."""
    pts = np.array(points, dtype=np.float64)
    keep = np.ones(len(pts), bool)
    for cov in covers:
        if cov.hides_all:
            return pts, np.zeros(len(pts), bool)
        flat = pts.reshape(-1, 3)
        rel = flat - sc.centre
        r = np.linalg.norm(rel, axis=1)
        u = rel / np.maximum(r[:, None], 1e-12)
        th = np.arctan2(u[:, 0], -u[:, 1])
        el = np.arcsin(np.clip(u[:, 2], -1, 1))
        n = len(cov.band)
        a = np.mod((np.degrees(th) + 180.0) / (360.0 / n), n)
        band = np.interp(a, np.arange(n + 1), np.concatenate([cov.band, cov.band[:1]]))
        skull = sc.radius_at(th, el)
        h = np.maximum(r - skull, 0.0)
        pressed = cov.room * (1.0 - np.exp(-h / cov.room))
        w = smoothstep((el - band) * skull / 0.025 + 1.0)  # 1 above the band, 0 from 2.5 cm below it
        new_r = skull + w * pressed + (1.0 - w) * h
        inside = r > skull  # points already under the skull surface are left alone
        flat = np.where(inside[:, None], sc.centre + new_r[:, None] * u, flat)
        pts = flat.reshape(pts.shape)
        keep &= ~(el >= band).reshape(pts.shape[:2]).all(1)
    return pts, keep


def depth_under(vertices: np.ndarray, faces: np.ndarray, centre: np.ndarray, points: np.ndarray) -> np.ndarray:
    """How far (metres) each point lies under a headwear mesh, seen from the head's centre: the distance to the
    first hit of the ray from `centre` through the point (trimesh) minus the point's own distance; > 0 means the
    headwear is further out (the point is under it), -inf that the ray misses the headwear."""
    from .geometry import first_hit

    rel = np.asarray(points, np.float64) - centre
    r = np.linalg.norm(rel, axis=1)
    t = first_hit(vertices, faces, np.broadcast_to(centre, rel.shape), rel / np.maximum(r[:, None], 1e-12))
    return np.where(np.isfinite(t), t - r, -np.inf)
