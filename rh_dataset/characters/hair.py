"""Hair: volumes modelled in the rest pose around the head, then bound to the body so they follow every pose.

Every style is a smooth cap over the skull ("hair"); longer styles add a closed hair mass, buns a bun and ponytails a
swept tube. All parts are designed as explicit surfaces in rest-pose space and then bound to the body with
`geometry.bind_points`: each vertex becomes a convex blend of (Gaussian-smoothed) body vertices plus an offset along
the blended normal - the same `blend_vertices` / `blend_weights` anchoring skirts use, so `pose_character` moves hair
with the head, neck and back and reproduces the designed shape exactly in the rest pose.

- Cap: a latitude/longitude grid about a point inside the skull, from the crown (a whorl) down to a smooth,
  azimuth-dependent hairline (high on the forehead, above the ears, down to the nape). The skull's radius along each
  direction is a kernel regression of the head vertices' radii (ears excluded), so the cap is smooth however coarse
  the scalp mesh is; the hair's thickness (style-dependent, 1.5-4 cm on top) tapers to ~2 mm at the hairline.
- Bob / long ("hair_curtain"): a closed slab - outer and inner surfaces joined by strips along the hem, the front
  edges and the (hidden) top - that starts inside the cap, widens with it and falls vertically from the widest point
  of the head, over the ears, shoulders and back (a hanging envelope of the body and clothes, per azimuth).
- Bun ("hair_bun"): a closed, slightly twisted ellipsoid at the back of the crown.
- Ponytail ("hair_ponytail"): a closed tube swept along a curve from a tie at the back of the head down the neck.

UVs ("own" layout, `HAIR_METRES_PER_UV` metres per unit in both directions): u runs across the hair, v along the
strands (v = 1 at the crown, decreasing towards the tips), so the strand texture's streaks follow the hair flow.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from rh_common.body_model import ANNY_TOPOLOGY

from .garments import PartGeometry, _smoothstep
from .body_features import BodyFeatures
from .geometry import bind_points, closed_tube, drop_unreferenced, surface_clearance

__all__ = ["build_hair", "hair_frame", "CAP_THICKNESS", "HAIR_METRES_PER_UV", "HAIR_PARTS"]

# Thickness of the cap on the crown (metres); the sides get a fraction of it and the hairline ~2 mm.
CAP_THICKNESS = {"buzz": 0.004, "short": 0.026, "bob": 0.03, "long": 0.026, "bun": 0.014, "ponytail": 0.014}
HAIR_METRES_PER_UV = 0.7
HAIR_PARTS = {
    "buzz": ("hair",),
    "short": ("hair",),
    "bob": ("hair", "hair_curtain"),
    "long": ("hair", "hair_curtain"),
    "bun": ("hair", "hair_bun"),
    "ponytail": ("hair", "hair_ponytail"),
}
_N_AZ = 72  # cap columns (5 degrees)
_E_DENSE = np.radians(np.arange(90.0, -70.0, -2.0))  # elevations the skull profile is sampled at
_BIND_SMOOTH = 0.02  # metres: Gaussian radius of the anchor surface hair is bound to
_BIND_SMOOTH_FAR = 0.035  # for hair hanging centimetres off the neck and back: a smoother normal field


def hair_frame(feats: BodyFeatures) -> tuple[np.ndarray, float]:
    """Centre of the skull (the cap's polar origin) and the eyes' height."""
    hb = feats.bone_heads["head"]
    z_eye = 0.5 * float(feats.bone_heads["eye.L"][2] + feats.bone_heads["eye.R"][2])
    return np.array([hb[0], hb[1] + 0.005, z_eye - 0.005]), z_eye


def _dirs(theta: np.ndarray, elev: np.ndarray) -> np.ndarray:
    """Unit vectors; azimuth theta from -Y (front) towards +X (the character's left), elevation from horizontal."""
    ce = np.cos(elev)
    return np.stack([np.sin(theta) * ce, -np.cos(theta) * ce, np.sin(elev) + 0.0 * theta], axis=-1)


def _skull_radius(feats: BodyFeatures, centre: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Radius of the head surface along unit `dirs` (..., 3): a Gaussian kernel regression (sigma ~6 degrees) of the
    outward-facing head/neck vertices' distances from `centre`, ears excluded (hair covers them)."""
    v, n = feats.rest_vertices, feats.rest_normals
    rel = v - centre
    r = np.linalg.norm(rel, axis=1)
    u = rel / np.maximum(r[:, None], 1e-9)
    m = feats.in_groups("head", "neck") & (feats.masks["ears"] < 0.2) & ((n * u).sum(1) > 0.3)
    u, r = u[m], r[m]
    flat = dirs.reshape(-1, 3)
    out = np.empty(len(flat))
    kappa = 1.0 / np.radians(6.0) ** 2
    for s in range(0, len(flat), 2048):
        w = np.exp(kappa * (flat[s:s + 2048] @ u.T - 1.0))
        out[s:s + 2048] = (w @ r) / np.maximum(w.sum(1), 1e-300)
    return out.reshape(dirs.shape[:-1])


def _hairline_height(style: str, feats: BodyFeatures, theta: np.ndarray) -> np.ndarray:
    """Height (metres) of the hairline as a function of azimuth: forehead, temples, above the ear, nape."""
    _, z_eye = hair_frame(feats)
    hb = feats.bone_heads["head"]
    nape = {"buzz": -0.03, "short": -0.04, "bob": -0.05, "long": -0.05, "bun": -0.035, "ponytail": -0.035}[style]
    # Forehead (slightly receding at the temples), sideburn in front of the ear, over the ear, behind it down to a
    # nape that runs nearly level across the back of the neck.
    knots = np.array([0.0, 25.0, 45.0, 62.0, 78.0, 92.0, 108.0, 122.0, 140.0, 180.0])
    heights = np.array([z_eye + 0.05, z_eye + 0.052, z_eye + 0.046, z_eye + 0.03, z_eye + 0.0, z_eye + 0.02,
                        z_eye + 0.012, hb[2] + 0.0, hb[2] + 0.85 * nape, hb[2] + nape])
    return np.interp(np.abs(np.degrees(theta)), knots, heights)


def _cap_profile(style: str, feats: BodyFeatures):
    """Skull radius r (A, E), hairline elevation e_h (A,) and cap thickness th (A, E) on the (azimuth, _E_DENSE)
    grid; azimuths are the cap's columns -180 + 5 k degrees."""
    centre, _ = hair_frame(feats)
    theta = np.radians(-180.0 + 360.0 * np.arange(_N_AZ) / _N_AZ)
    tt, ee = np.meshgrid(theta, _E_DENSE, indexing="ij")
    r = _skull_radius(feats, centre, _dirs(tt, ee))
    z = centre[2] + r * np.sin(ee)
    line = _hairline_height(style, feats, theta)
    e_h = np.empty(_N_AZ)
    for a in range(_N_AZ):
        below = np.flatnonzero(z[a] < line[a])
        k = int(below[0]) if len(below) else len(_E_DENSE) - 1
        k = max(k, 1)
        z0, z1 = z[a, k - 1], z[a, k]
        f = float(np.clip((z0 - line[a]) / max(z0 - z1, 1e-9), 0.0, 1.0))
        e_h[a] = _E_DENSE[k - 1] + f * (_E_DENSE[k] - _E_DENSE[k - 1])
    e_h = ndimage.gaussian_filter1d(e_h, 1.2, mode="wrap")  # a smooth hairline
    top = CAP_THICKNESS[style]
    edge = 0.0015 if style == "buzz" else 0.002
    taper = 0.008 if style == "buzz" else 0.04
    arc = r * (ee - e_h[:, None])  # metres above the hairline along the meridian
    fuller = 0.45 + 0.55 * _smoothstep((np.sin(ee) - 0.1) / 0.8)  # fuller on the crown than on the sides
    ramp = _smoothstep(arc / taper)
    if style in ("bob", "long"):
        fuller = np.maximum(fuller, 0.7)
    th = edge + (top * fuller - edge) * ramp ** 0.75
    return theta, r, e_h, th


def _interp_rows(values: np.ndarray, e: np.ndarray) -> np.ndarray:
    """values (A, E) on _E_DENSE (descending) at elevations e (A, R) per azimuth row."""
    out = np.empty(e.shape)
    for a in range(len(values)):
        out[a] = np.interp(-e[a], -_E_DENSE, values[a])
    return out


def _push_out(points: np.ndarray, feats: BodyFeatures, cand: np.ndarray, under: np.ndarray, margin: float,
              direction: np.ndarray) -> np.ndarray:
    """Move points along `direction` (unit, per point) until they are `margin` outside the body and clothes."""
    v = feats.rest_vertices + under[:, None] * feats.rest_normals
    p = points.copy()
    for _ in range(3):
        h = surface_clearance(p, v, feats.rest_normals, cand)
        need = np.maximum(margin - h, 0.0)
        if not need.any():
            break
        p += need[:, None] * direction * 1.1
    return p


def _grid_faces(n_rows: int, n_cols: int, pole_first: bool = False) -> np.ndarray:
    """Triangles of a (rows x cols) vertex grid (row-major); with pole_first, row 0 is a pole (one triangle per
    column between rows 0 and 1)."""
    faces = []
    for j in range(n_rows - 1):
        for c in range(n_cols - 1):
            a, b = j * n_cols + c, j * n_cols + c + 1
            d, e = a + n_cols, b + n_cols
            if j == 0 and pole_first:
                faces.append((a, d, e))
            else:
                faces += [(a, d, b), (b, d, e)]
    return np.array(faces, dtype=np.int64).reshape(-1, 3)


def _orient(verts: np.ndarray, faces: np.ndarray, centre: np.ndarray | None = None) -> np.ndarray:
    """Flip faces so normals point outwards: closed meshes by signed volume, open ones away from `centre`."""
    tri = verts[faces]
    cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    if centre is None:
        s = float((cr * tri[:, 0]).sum())
    else:
        s = float((cr * (tri.mean(1) - centre)).sum())
    return faces if s > 0 else faces[:, ::-1].copy()


def _close_slab(n_outer: int, faces_outer: np.ndarray) -> np.ndarray:
    """Faces of a closed slab from an open outer surface (vertices 0..n-1) and its inner copy (n..2n-1): inner
    surface reversed plus a strip along every boundary edge."""
    inner = faces_outer[:, ::-1] + n_outer
    e = np.concatenate([faces_outer[:, [0, 1]], faces_outer[:, [1, 2]], faces_outer[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = e[counts[inv.ravel()] == 1]  # directed as the outer surface runs along them
    p, q = boundary[:, 0], boundary[:, 1]
    strip = np.concatenate([np.stack([q, p, p + n_outer], 1), np.stack([q, p + n_outer, q + n_outer], 1)])
    return np.concatenate([faces_outer, inner, strip])


def _bind(name: str, verts: np.ndarray, faces: np.ndarray, uvs: np.ndarray, feats: BodyFeatures,
          region: np.ndarray, under: np.ndarray, smooth: float = _BIND_SMOOTH) -> PartGeometry:
    verts, faces, uvs = drop_unreferenced(verts, faces, uvs)
    b = bind_points(verts, region, feats, smooth_radius=smooth)
    # Where the binding could not reproduce a point exactly (the edge of the anchor region, converging normals),
    # make sure the reconstructed point is still clear of the skin and clothes: raise its offset.
    v, n = feats.rest_vertices, feats.rest_normals
    w = b.blend_weights.astype(np.float64)[..., None]
    base = (v[b.blend_vertices] * w).sum(1)
    nb = (n[b.blend_vertices] * w).sum(1)
    nb /= np.maximum(np.linalg.norm(nb, axis=1, keepdims=True), 1e-12)
    off = b.offset.astype(np.float64)
    cand = np.flatnonzero(feats.in_groups("head", "neck", "torso", "shoulder", "upperarm"))
    surf = v + under[:, None] * n
    for _ in range(3):
        h = surface_clearance(base + off[:, None] * nb, surf, n, cand)
        need = np.maximum(0.0015 - h, 0.0)
        if not need.any():
            break
        off += 1.2 * need
    return PartGeometry(
        name=name,
        faces=faces.astype(np.int32),
        uvs=np.clip(uvs, 0.0, 1.0).astype(np.float32),
        body_vertex=b.body_vertex,
        offset=off.astype(np.float32),
        uv_layout="own",
        metres_per_uv=HAIR_METRES_PER_UV,
        blend_vertices=b.blend_vertices,
        blend_weights=b.blend_weights,
    )


def _cap(style: str, feats: BodyFeatures, under: np.ndarray, prof, n_rows: int = 22):
    """The cap's vertices (R, A+1, 3) (the last column repeats the first: a UV seam at the back), faces, UVs."""
    centre, _ = hair_frame(feats)
    theta, r, e_h, th = prof
    t = np.linspace(0.0, 1.0, n_rows) ** 0.85
    e = np.pi / 2 - (np.pi / 2 - e_h[:, None]) * t[None, :]  # (A, R)
    rad = _interp_rows(r + th, e)
    pts = centre + rad[..., None] * _dirs(theta[:, None], e)  # (A, R, 3)
    pts[:, 0] = pts[:, 0].mean(0)  # the crown: one point whatever the column
    flat = pts.reshape(-1, 3)
    d = flat - centre
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    cand = np.flatnonzero(feats.in_groups("head", "neck"))
    flat = _push_out(flat, feats, cand, under, 0.0015, d)
    pts = flat.reshape(pts.shape).transpose(1, 0, 2)  # (R, A, 3)
    pts = np.concatenate([pts, pts[:, :1]], axis=1)  # seam column
    arc = np.concatenate([np.zeros((_N_AZ, 1)), np.cumsum(np.linalg.norm(np.diff(pts[:, :-1].transpose(1, 0, 2),
                                                                                  axis=1), axis=2), 1)], 1)
    u = (np.arange(_N_AZ + 1) / _N_AZ) * 2 * np.pi * float(np.median(r)) / HAIR_METRES_PER_UV
    v = 1.0 - np.concatenate([arc, arc[:1]], 0).T / HAIR_METRES_PER_UV  # (R, A+1)
    uvs = np.stack([np.broadcast_to(u, v.shape), v], -1).reshape(-1, 2)
    faces = _grid_faces(n_rows, _N_AZ + 1, pole_first=True)
    verts = pts.reshape(-1, 3)
    return verts, _orient(verts, faces, centre), uvs, float(arc.mean(0)[-1])


def _body_cylinder(feats: BodyFeatures, under: np.ndarray, centre: np.ndarray, z_lo: float, z_hi: float,
                   dz: float = 0.006):
    """Per (azimuth bin of 5 degrees, height bin) the largest horizontal distance from the head's vertical axis of
    the head, neck, trunk and shoulders (clothes included): (grid (A, Z), z of the bins)."""
    m = feats.in_groups("head", "neck", "torso", "shoulder")
    p = feats.rest_vertices[m] + under[m, None] * feats.rest_normals[m]
    rel = p[:, :2] - centre[:2]
    az = np.degrees(np.arctan2(rel[:, 0], -rel[:, 1])) % 360.0
    rho = np.hypot(rel[:, 0], rel[:, 1])
    zs = np.arange(z_hi, z_lo - dz, -dz)  # top down
    ai = np.floor(az / (360.0 / _N_AZ)).astype(np.int64) % _N_AZ
    zi = np.round((z_hi - p[:, 2]) / dz).astype(np.int64)
    ok = (zi >= 0) & (zi < len(zs))
    grid = np.zeros((_N_AZ, len(zs)))
    np.maximum.at(grid, (ai[ok], zi[ok]), rho[ok])
    grid = ndimage.maximum_filter(grid, size=(3, 3), mode=("wrap", "nearest"))
    return grid, zs


def _sample(grid: np.ndarray, zs: np.ndarray, az_deg: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Bilinear lookup of an (azimuth bin, z bin) grid (azimuth bin centres at (k + 0.5) * 5 degrees, wrapping)."""
    pad = np.concatenate([grid[-1:], grid, grid[:1]], 0)
    a = (az_deg % 360.0) / (360.0 / _N_AZ) - 0.5 + 1.0
    zi = (zs[0] - z) / (zs[0] - zs[1])
    return ndimage.map_coordinates(pad, [a.ravel(), zi.ravel()], order=1, mode="nearest").reshape(np.shape(z))


def _curtain(style: str, feats: BodyFeatures, under: np.ndarray, prof, arc_cap: float):
    """A closed hair mass falling from the cap (bob: to the chin, long: down the back)."""
    centre, z_eye = hair_frame(feats)
    theta, r, e_h, th = prof
    z_sh = 0.5 * float(feats.bone_heads["shoulder01.L"][2] + feats.bone_heads["shoulder01.R"][2])
    z_top = centre[2] + 0.045
    if style == "bob":
        z_hem = z_eye - 0.1
    else:
        z_hem = float(feats.bone_heads["spine02"][2]) + 0.03
    grid_b, zs = _body_cylinder(feats, under, centre, z_hem - 0.05, z_top + 0.06)
    # The cap's outer surface, rasterised on the same grid (2 mm inside it), so the mass leaves the cap tangentially.
    grid_c = np.full_like(grid_b, -np.inf)
    ee = np.broadcast_to(_E_DENSE, r.shape)
    rad = r + th
    zc = centre[2] + rad * np.sin(ee)
    rc = rad * np.cos(ee)
    shift = _N_AZ // 2  # cap azimuths start at -180 degrees, the grid's at 0
    for a in range(_N_AZ):
        ok = _E_DENSE >= e_h[a]
        zz, rr = zc[a, ok][::-1], rc[a, ok][::-1]  # ascending z
        inside = (zs >= zz.min()) & (zs <= zz.max())
        # Cap columns sit at -180 + 5a degrees, i.e. on the grid's bin edges: put them on the bin to their right.
        grid_c[(a + shift) % _N_AZ, inside] = np.interp(zs[inside], zz, rr) - 0.002
    grid_c = np.maximum(grid_c, np.roll(grid_c, 1, axis=0))
    clear = 0.009
    # Hair falls vertically from the widest point above (cumulative max downwards) and starts widening ~3 cm above
    # an obstacle such as an ear or a shoulder (max over a window below).
    need = np.maximum(grid_c, ndimage.maximum_filter1d(grid_b + clear, 7, axis=1, origin=-3, mode="nearest"))
    hang = np.maximum.accumulate(need, axis=1)
    smooth = ndimage.gaussian_filter(hang, (0.8, 1.5), mode=("wrap", "nearest"))
    hang = ndimage.gaussian_filter(np.maximum(smooth, hang), (0.5, 0.8), mode=("wrap", "nearest"))
    body = ndimage.gaussian_filter(grid_b, (0.6, 0.8), mode=("wrap", "nearest"))

    n_cols = 37
    n_rows = 20 if style == "bob" else 30
    s = np.linspace(0.0, 1.0, n_cols)
    t = np.linspace(0.0, 1.0, n_rows) ** 1.2
    if style == "bob":
        half = np.full(n_rows, 116.0)
        zh = z_hem - 0.012 * (2 * s - 1) ** 2  # a little longer at the front corners
    else:
        z_chin = z_eye - 0.09
        zz = z_top + (z_hem - z_top) * t
        half = 116.0 - 48.0 * _smoothstep((z_chin - zz) / max(z_chin - (z_sh - 0.03), 1e-3))
        zh = z_hem + 0.05 * (2 * s - 1) ** 2  # a U-shaped ends, longer in the middle
    az = 180.0 + (2 * s[None, :] - 1) * half[:, None]  # (R, C) degrees in [0, 360)
    # The top row starts higher at the front edges, where the cap is thin, so it is hidden under the cap everywhere.
    zt = z_top + 0.03 * _smoothstep((np.abs(2 * s - 1) - 0.6) / 0.4)
    z = zt[None, :] + (zh[None, :] - zt[None, :]) * t[:, None]
    rho_o = _sample(hang, zs, az, z)
    thick = 0.016 - 0.009 * _smoothstep((t[:, None] - 0.6) / 0.4)
    rho_b = _sample(body, zs, az, z)
    if style == "bob":  # the ends curl in a little under the jaw
        curl = 0.008 * _smoothstep((t[:, None] - 0.8) / 0.2)
        rho_o = np.maximum(rho_o - curl, rho_b + 0.01)
    rho_i = np.minimum(np.maximum(rho_o - thick, rho_b + 0.003), rho_o - 0.003)
    a = np.radians(az)

    def pts(rho):
        return np.stack([centre[0] + rho * np.sin(a), centre[1] - rho * np.cos(a), z], -1).reshape(-1, 3)

    outer, inner = pts(rho_o), pts(rho_i)
    # Columns run from the character's right round the back to its left; u in metres across at mid height.
    width = float(np.median(rho_o)) * np.radians(2 * half.max())
    u = 0.5 + (s - 0.5) * width / HAIR_METRES_PER_UV
    seg = np.linalg.norm(np.diff(outer.reshape(n_rows, n_cols, 3), axis=0), axis=2)
    arc = arc_cap * 0.8 + np.concatenate([np.zeros((1, n_cols)), np.cumsum(seg, 0)], 0)
    v = 1.0 - arc / HAIR_METRES_PER_UV
    uv = np.stack([np.broadcast_to(u, v.shape), v], -1).reshape(-1, 2)
    faces = _close_slab(len(outer), _grid_faces(n_rows, n_cols))
    verts = np.concatenate([outer, inner])
    return verts, _orient(verts, faces), np.concatenate([uv, uv])


def _tube(rings: np.ndarray, start: np.ndarray, end: np.ndarray, u_scale: float, v0: float,
          arc: np.ndarray):
    """A closed tube: rings (S, K, 3) plus pole points at both ends; seam column duplicated for UVs."""
    S, K, _ = rings.shape
    n_rows, n_cols = S + 2, K + 1
    verts, faces = closed_tube(rings, start, end)
    u = (np.arange(n_cols) / K) * u_scale
    arc_full = np.concatenate([[arc[0]], arc, [arc[-1] + 0.004]])
    v = v0 - arc_full / HAIR_METRES_PER_UV
    uv = np.stack(np.broadcast_arrays(u[None, :], v[:, None]), -1).reshape(-1, 2)
    return verts, _orient(verts, faces), uv


def _frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ref = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    b1 = np.cross(axis, ref)
    b1 /= np.linalg.norm(b1)
    return b1, np.cross(axis, b1)


def _bun(style: str, feats: BodyFeatures, prof, arc_cap: float):
    centre, _ = hair_frame(feats)
    theta, r, e_h, th = prof
    e_b = np.radians(42.0)
    rad = float(np.interp(-e_b, -_E_DENSE, (r + th)[0]))  # column 0: azimuth -180 degrees, the back
    out = _dirs(np.array(np.pi), np.array(e_b))
    rb = 0.4 * float(np.median(r))
    c = centre + rad * out + 0.45 * rb * out
    b1, b2 = _frame(out)
    n_lat, n_lon = 12, 28
    lat = np.linspace(0.0, np.pi, n_lat + 2)[1:-1]  # from the outer pole to the inner one
    lon = np.linspace(0.0, 2 * np.pi, n_lon, endpoint=False)
    L, P = np.meshgrid(lat, lon, indexing="ij")
    twist = 1.0 + 0.07 * np.sin(3 * P + 5 * L) * np.sin(L)  # a coiled look
    local = np.stack([np.cos(L) * 0.8, np.sin(L) * np.cos(P), np.sin(L) * np.sin(P)], -1) * (rb * twist)[..., None]
    rings = c + local[..., :1] * out + local[..., 1:2] * b1 + local[..., 2:] * b2
    arc = lat * rb
    return _tube(rings, c + 0.8 * rb * out, c - 0.8 * rb * out, 2 * np.pi * rb / HAIR_METRES_PER_UV,
                 1.0 - arc_cap / HAIR_METRES_PER_UV, arc)


def _ponytail(feats: BodyFeatures, under: np.ndarray, prof, arc_cap: float):
    centre, z_eye = hair_frame(feats)
    theta, r, e_h, th = prof
    e_t = np.radians(8.0)
    rad = float(np.interp(-e_t, -_E_DENSE, (r + th)[0]))
    out = _dirs(np.array(np.pi), np.array(e_t))  # backwards
    tie = centre + rad * out
    length = 0.3
    s = np.linspace(0.0, 1.0, 26)
    # Quadratic Bezier: out of the tie, then hanging down.
    p0 = tie - 0.012 * out
    p1 = tie + 0.07 * out + np.array([0.0, 0.0, 0.01])
    p2 = p1 + np.array([0.0, 0.03, -length])
    curve = ((1 - s) ** 2)[:, None] * p0 + (2 * (1 - s) * s)[:, None] * p1 + (s ** 2)[:, None] * p2
    radius = np.interp(s, [0.0, 0.05, 0.09, 0.25, 0.7, 1.0], [0.011, 0.011, 0.017, 0.02, 0.012, 0.003])
    n_around = 16
    ang = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    cand = np.flatnonzero(feats.in_groups("head", "neck", "torso", "shoulder"))
    vbody = feats.rest_vertices + under[:, None] * feats.rest_normals
    for _ in range(3):  # keep the tube off the neck and back: shift rings backwards, never forwards again
        tang = np.gradient(curve, axis=0)
        tang /= np.linalg.norm(tang, axis=1, keepdims=True)
        rings = _rings(curve, tang, radius, ang)
        h = surface_clearance(rings.reshape(-1, 3), vbody, feats.rest_normals, cand).reshape(len(s), -1).min(1)
        need = np.maximum(0.006 - h, 0.0)
        need[s < 0.15] = 0.0
        if not need.any():
            break
        need = np.maximum.accumulate(ndimage.gaussian_filter1d(need, 1.5) * 1.3 + need)
        curve = curve + need[:, None] * np.array([0.0, 1.0, 0.0])
    tang = np.gradient(curve, axis=0)
    tang /= np.linalg.norm(tang, axis=1, keepdims=True)
    rings = _rings(curve, tang, radius, ang)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
    return _tube(rings, curve[0] - 0.004 * tang[0], curve[-1] + 0.003 * tang[-1],
                 2 * np.pi * 0.018 / HAIR_METRES_PER_UV, 1.0 - arc_cap / HAIR_METRES_PER_UV, arc)


def _rings(curve, tang, radius, ang):
    out = []
    for p, t, rr in zip(curve, tang, radius):
        side = np.cross(t, [0.0, 1.0, 0.0])
        if np.linalg.norm(side) < 1e-6:
            side = np.array([1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        nrm = np.cross(side, t)
        # Slightly flattened front to back, as a ponytail lying against the neck is.
        out.append(p + rr * (np.cos(ang)[:, None] * side + 0.8 * np.sin(ang)[:, None] * nrm))
    return np.array(out)


def build_hair(
    style: str, feats: BodyFeatures, topology: str = ANNY_TOPOLOGY, under: np.ndarray | None = None
) -> list[PartGeometry]:
    """Hair parts for a style (names in `HAIR_PARTS[style]`): the cap "hair", plus a closed "hair_curtain" (bob,
    long), "hair_bun" or "hair_ponytail".

    `under` (V,) is the outermost garment offset per body vertex (see `build_garments`); hair stays outside it.
    """
    if topology != ANNY_TOPOLOGY:
        raise ValueError(f"build_hair: only {ANNY_TOPOLOGY!r} is supported")
    if under is None:
        under = np.zeros(len(feats.rest_vertices))
    prof = _cap_profile(style, feats)
    head_region = np.flatnonzero(feats.in_groups("head", "neck"))
    # Hair lying on the shoulders may project onto the top of the upper arm: include it, or the anchor surface
    # would have a hole there.
    upper = np.flatnonzero(feats.in_groups("head", "neck", "torso", "shoulder", "upperarm"))
    verts, faces, uvs, arc_cap = _cap(style, feats, under, prof)
    parts = [_bind("hair", verts, faces, uvs, feats, head_region, under)]
    if style in ("bob", "long"):
        parts.append(_bind("hair_curtain", *_curtain(style, feats, under, prof, arc_cap), feats, upper, under,
                           smooth=_BIND_SMOOTH_FAR))
    elif style == "bun":
        parts.append(_bind("hair_bun", *_bun(style, feats, prof, arc_cap), feats, head_region, under))
    elif style == "ponytail":
        parts.append(_bind("hair_ponytail", *_ponytail(feats, under, prof, arc_cap), feats, upper, under,
                           smooth=_BIND_SMOOTH_FAR))
    return parts
