"""The loose tops' sleeves, cut as two cloth tubes that newton drapes (drape.py's `draped_sleeves`: the loose
t-shirt's short sleeves; `draped_long_sleeves`: the loose long sleeve's, down to the wrist; `draped_hoodie_sleeves`:
the hoodie's, the long cut in the hood's fleece; `draped_coat_sleeves`: the open coat's, the long cut kept farther off
the arm, over the top's sleeve).

In: a phenotype, the sleeves' `DrapeSettings` (drape.py) and their cut (`SleeveCut`: `SLEEVES`, `LONG_SLEEVES`;
`SLEEVE_CUTS` by kind).
Out: `sleeve_pattern`, the undraped cloth (two closed tubes around the arms in anny's A-pose, each pinned at its top
ring), which `drape.drape_garment` simulates and caches like any draped kind; `sleeve_tops`, where each pinned ring
lies along its upper arm (for a cut's `ring_gap`), which the shells "tee", "longtop", "hoodie" and "coat" (garments.py)
are cut to end just under (`SHELL_OVERLAP`), as their hems end under the cloth body's ring; `sleeves_render_mesh`, the
tubes' render mesh with UVs in metres of the cut.

Why cloth: the shell's sleeve follows the arm at 6 mm, where a loose top's sleeve stands off the arm, hangs open
below it and shades it. The long sleeve's tube bends with the elbow, which anny's A-pose already bends by ~42
degrees: its axis turns from the upper arm's to the forearm's over `SleeveCut.bend` either side of the elbow joint.
Under an open jacket or coat the jacket's shell sleeve lies over the arm at 17 mm, which the cloth would come
through (garments.garment_parts leaves the sleeves out there).
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np

__all__ = ["SleeveCut", "SLEEVES", "LONG_SLEEVES", "COAT_SLEEVES", "SLEEVE_CUTS", "SIDES", "sleeve_axis", "sleeve_tops",
           "sleeve_pattern", "sleeves_render_mesh"]

SIDES = ("L", "R")


@dataclasses.dataclass(frozen=True)
class SleeveCut:
    """The cut of a loose short sleeve along its upper arm (the axis from the upperarm01 joint to the lowerarm01
    joint in anny's A-pose, where the arm hangs ~42 degrees from the vertical). The pinned ring is the first ring
    (perpendicular to the axis, `ring_gap` metres outside the convex hull of the arm's cross-section there) that
    keeps `ring_gap` off the rest of the body (the armpit, the chest, the back), searched from `top_from` metres
    along the axis in `top_step` steps up to `top_to`; the tube runs from there to `hem` times the shoulder-to-wrist
    distance (the shell t-shirt's sleeve ends at 0.3), widening at `flare` radians, each ring kept `gap` outside
    the arm's hull (its particle radius plus 2 mm is the drape's).
    `elbow`: the tube follows the forearm past the elbow (the long sleeve's): its axis is the upper arm's to `bend`
    metres before the lowerarm01 joint and the forearm's (to the wrist joint) from `bend` after it, turning between
    by a smoothstep, and `hem` is then a fraction of the axis's length from the upperarm01 joint to the wrist.
    `taper`: how fast (metres of radius per metre along the axis) a ring may narrow where the arm does, at most down
    to `gap` outside it (0: a ring is never narrower than the one above it, the short sleeve's cone)."""

    ring_gap: float = 0.008
    gap: float = 0.008
    hem: float = 0.34
    flare: float = 0.2
    top_from: float = 0.03
    top_step: float = 0.005
    top_to: float = 0.15
    band: float = 0.012  # metres along the axis either side of a ring whose arm vertices make its cross-section
    elbow: bool = False
    bend: float = 0.06
    taper: float = 0.0
    band_below: float | None = None  # `band` for the rings below the pinned one (None: `band`)


SLEEVES = SleeveCut()
# The loose long sleeve's: to 0.93 of the way to the wrist joint (the shell longsleeve's cuff is at 0.95 of the
# straight shoulder-to-wrist distance, which the bent axis's length exceeds by ~6 %), no flare, narrowing by at most
# 1 mm a centimetre towards the wrist, where the forearm is some 2 cm thinner than the upper arm.
LONG_SLEEVES = SleeveCut(hem=0.93, flare=0.0, elbow=True, taper=0.1, band_below=0.02)
# The hoodie's sleeves are the long sleeve's cut, draped in the hood's fleece (drape.py).
# The open coat's: the long sleeve's cut worn over another top's shell sleeve (6 mm over the arm), so the rings and
# tube keep COAT_GAP off the arm (the coat's particle radius, drape.COAT_CLEARANCE, plus 2 mm, as the other cuts keep
# theirs): the pinned ring sits farther down the arm, where it clears the trunk by that much.
COAT_GAP = 0.016
COAT_SLEEVES = dataclasses.replace(LONG_SLEEVES, ring_gap=COAT_GAP, gap=COAT_GAP)
SLEEVE_CUTS = {"draped_sleeves": SLEEVES, "draped_long_sleeves": LONG_SLEEVES, "draped_hoodie_sleeves": LONG_SLEEVES,
               "draped_coat_sleeves": COAT_SLEEVES}


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x)


def sleeve_axis(heads: dict, side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(origin, axis, p, q) of a side's upper arm, `heads` a bone label -> joint position map: the upperarm01 joint,
    the unit axis towards the lowerarm01 joint, and two unit directions across it (p: the arm's upper side, q = p x
    axis: so a ring's angle turns as the drape's body tubes' do, and `drape._grid_faces` faces outwards)."""
    o = np.asarray(heads[f"upperarm01.{side}"], np.float64)
    a = _unit(np.asarray(heads[f"lowerarm01.{side}"], np.float64) - o)
    p = _unit(np.array([0.0, 0.0, 1.0]) - a[2] * a)
    return o, a, p, np.cross(p, a)


def _centreline(heads: dict, side: str, ts: np.ndarray, cut: SleeveCut):
    """The long sleeve's bent axis (`SleeveCut.elbow`) at arc lengths `ts` (metres from the upperarm01 joint):
    (centres (N, 3), unit tangents (N, 3), p (N, 3), q (N, 3)), p and q turned with the tangent (about the normal of
    the plane the upper arm and forearm span), so the rings' particles do not twist along the tube; and the axis's
    length to the wrist joint. Integrated in 1 mm steps."""
    o, a, p, _ = sleeve_axis(heads, side)
    e = np.asarray(heads[f"lowerarm01.{side}"], np.float64)
    w = np.asarray(heads[f"wrist.{side}"], np.float64)
    b = _unit(w - e)
    n = np.cross(a, b)
    theta = float(np.arctan2(np.linalg.norm(n), a @ b))
    n = _unit(n)
    l1 = float(np.linalg.norm(e - o))

    def turn(s):
        x = np.clip((s - (l1 - cut.bend)) / (2.0 * cut.bend), 0.0, 1.0)
        return theta * x * x * (3.0 - 2.0 * x)

    def rotate(v, phi):  # Rodrigues, about n, for each angle in phi
        c, s = np.cos(phi)[:, None], np.sin(phi)[:, None]
        return v * c + np.cross(n, v)[None, :] * s + np.outer(1.0 - c[:, 0], n * (n @ v))

    grid = np.arange(0.0, l1 + cut.bend + float(np.linalg.norm(w - e)) + 0.05, 0.001)
    tang = rotate(a, turn(grid))
    steps = 0.5 * (tang[1:] + tang[:-1]) * 0.001
    pos = o + np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)])
    # The axis's length to the wrist: past the bend it runs along the forearm's direction b, so the arc length at
    # which it comes level with the wrist joint along b.
    past = grid >= l1 + cut.bend
    i0 = int(np.argmax(past))
    length = float(grid[i0] + (w - pos[i0]) @ b)
    ts = np.asarray(ts, np.float64)
    centre = np.stack([np.interp(ts, grid, pos[:, k]) for k in range(3)], axis=1)
    d, pp = rotate(a, turn(ts)), rotate(p, turn(ts))
    return centre, d, pp, np.cross(pp, d), length


def _arm_section(points: np.ndarray, o, a, p, q, t: float, band: float, ang: np.ndarray,
                 near: float | None = None) -> np.ndarray:
    """Radii (N,) at `ang` of the convex hull of the cross-section of `points` (an arm's vertices) within `band` of
    `t` metres along the axis (`o` + `t` `a`, the section's plane spanned by `p` and `q`); with `near`, only points
    within `near` metres of the axis (past the elbow the plane across the upper arm also cuts the forearm)."""
    from .geometry import hull_anchors

    rel = points - o
    along = rel @ a - t
    keep = np.abs(along) < band
    if near is not None:
        keep &= np.linalg.norm(rel - (rel @ a)[:, None] * a, axis=1) < near
    sel = np.flatnonzero(keep)
    if len(sel) < 3:
        raise ValueError(f"sleeves: too few arm vertices {t:.3f} m along the arm; is the body an adult's?")
    xy = np.c_[rel[sel] @ q, -(rel[sel] @ p), np.zeros(len(sel))]  # (hull_anchors: angle from -Y towards +X)
    idx, w = hull_anchors(xy, np.arange(len(sel)), np.zeros(2), ang)
    return np.linalg.norm((xy[idx, :2] * w[..., None]).sum(1), axis=1)


def _ring(o, a, p, q, t: float, r: np.ndarray, ang: np.ndarray) -> np.ndarray:
    return o + t * a + (r * np.cos(ang))[:, None] * p + (r * np.sin(ang))[:, None] * q


def _frame(phenotype: dict[str, float]):
    from .body import body_topology, run_anny
    from .body_features import body_features

    run = run_anny(phenotype)
    heads = {label: run["bone_poses"][i, :3, 3] for i, label in enumerate(body_topology().bone_labels)}
    return run["vertices"], heads, body_features(phenotype)


def _tops(body, heads, feats, n_around: int, cut: SleeveCut) -> dict[str, float]:
    from .body import body_topology
    from .drape import penetration
    from .geometry import closest_point, query_mesh

    faces = body_topology().faces
    rest = ~feats.in_groups("upperarm", "lowerarm", "hand")
    mesh = query_mesh(body, faces[rest[faces].all(axis=1)])
    arm = feats.in_groups("upperarm", "lowerarm")
    ang = np.arange(n_around) * (2.0 * np.pi / n_around)
    out = {}
    for side in SIDES:
        o, a, p, q = sleeve_axis(heads, side)
        pts = body[arm & ((body[:, 0] > 0) == (side == "L"))]
        for t in np.arange(cut.top_from, cut.top_to + 1e-9, cut.top_step):
            ring = _ring(o, a, p, q, float(t), _arm_section(pts, o, a, p, q, float(t), cut.band, ang) + cut.ring_gap,
                         ang)
            # Off the rest of the body by the gap, and outside the body (a ring point deep in the chest of a heavy
            # body lies farther than the gap from its surface).
            if (closest_point(mesh, ring)[1].min() >= cut.ring_gap
                    and penetration(body, faces, ring).max() < 0.0):
                out[side] = float(t)
                break
        else:
            raise ValueError(f"sleeves: no ring around the {side} upper arm within {cut.top_to} m of the shoulder "
                             f"keeps {cut.ring_gap} m off the trunk; this body cannot wear the loose sleeves")
    return out


def sleeve_tops(phenotype: dict[str, float], n_around: int, cut: SleeveCut = SLEEVES) -> dict[str, float]:
    """{side: metres along its upper arm axis (`sleeve_axis`, from the upperarm01 joint) of the pinned ring} for a
    sleeve pattern of `n_around` particles a ring (the search tests those points). Cached per phenotype: a loose
    t-shirt's build asks twice, for the shell's cut and for the pattern (~0.3 s a search)."""
    return dict(_tops_cached(tuple(sorted((k, float(v)) for k, v in phenotype.items())), int(n_around), cut))


@functools.lru_cache(maxsize=16)
def _tops_cached(pheno_items: tuple[tuple[str, float], ...], n_around: int, cut: SleeveCut):
    body, heads, feats = _frame(dict(pheno_items))
    return tuple(_tops(body, heads, feats, n_around, cut).items())


def sleeve_pattern(phenotype: dict[str, float], n_around: int, n_rings: int, cut: SleeveCut = SLEEVES):
    """The undraped sleeves in the A-pose frame the drape simulates in: the left tube, then the right, each
    `n_rings` rings of `n_around` particles, ring 0 pinned. Returns (vertices (V, 3), faces (F, 3) int32 outward,
    uvs (V, 2) (metres of the cut over the returned scale: u around from the arm's upper side, v up from the hem),
    pinned (V,) bool, metres per UV, pieces: each tube's (rings, around) vertex grid)."""
    from .drape import _grid_faces

    body, heads, feats = _frame(phenotype)
    tops = sleeve_tops(phenotype, n_around, cut)
    arm = feats.in_groups("upperarm", "lowerarm")
    ang = np.arange(n_around) * (2.0 * np.pi / n_around)
    verts, pieces, uvs = [], [], []
    for k, side in enumerate(SIDES):
        o, a, p, q = sleeve_axis(heads, side)
        pts = body[arm & ((body[:, 0] > 0) == (side == "L"))]
        if cut.elbow:
            reach = cut.hem * _centreline(heads, side, np.zeros(1), cut)[4]
        else:
            reach = cut.hem * float(np.linalg.norm(np.asarray(heads[f"wrist.{side}"]) - o))
        if reach <= tops[side] + 0.02:
            raise ValueError(f"sleeves: the {side} sleeve's ring ({tops[side]:.3f} m along the arm) leaves under 2 cm "
                             f"of sleeve before its hem ({reach:.3f} m)")
        ts = np.linspace(tops[side], reach, n_rings)
        m = _arm_section(pts, o, a, p, q, ts[0], cut.band, ang) + cut.ring_gap
        rings = []
        if cut.elbow:
            centre, d, pp, qq, _ = _centreline(heads, side, ts, cut)
            for i, t in enumerate(ts):
                if i:  # narrowing with the arm by at most `taper`, never closer than `gap` to it (only the arm near
                    # the axis: the plane across the upper arm near the elbow also cuts the forearm)
                    hull = _arm_section(pts, centre[i], d[i], pp[i], qq[i], 0.0, cut.band_below or cut.band, ang,
                                        near=0.12)
                    m = np.maximum(m - cut.taper * (t - ts[i - 1]), hull + cut.gap)
                rings.append(_ring(centre[i], d[i], pp[i], qq[i], 0.0, m, ang))
        else:
            for i, t in enumerate(ts):
                out = (t - ts[0]) * np.tan(cut.flare)
                if i:  # the cone as cut where the arm stays inside it, pushed out (and kept out below) where it reaches
                    m = np.maximum(m, _arm_section(pts, o, a, p, q, float(t), cut.band, ang) + cut.gap - out)
                rings.append(_ring(o, a, p, q, float(t), m + out, ang))
        grid = k * n_rings * n_around + np.arange(n_rings * n_around).reshape(n_rings, n_around)
        v = np.concatenate(rings)
        verts.append(v)
        pieces.append(grid)
        uvs.append(np.stack(np.broadcast_arrays(ang[None, :] / (2.0 * np.pi), (ts[-1] - ts[:, None])), -1)
                   .reshape(-1, 2))
    verts = np.concatenate(verts)
    faces = np.concatenate([_grid_faces(g) for g in pieces]).astype(np.int32)
    circ = max(float(np.linalg.norm(verts[g[-1]] - verts[np.roll(g[-1], -1)], axis=1).sum()) for g in pieces)
    length = max(float(u[:, 1].max()) for u in uvs)
    mpu = max(circ, length)
    uv = np.concatenate(uvs) * np.array([circ, 1.0]) / mpu
    pinned = np.zeros(len(verts), dtype=bool)
    for g in pieces:
        pinned[g[0]] = True
    return verts, faces, np.clip(uv, 0.0, 1.0).astype(np.float32), pinned, mpu, tuple(pieces)


def sleeves_render_mesh(pattern: np.ndarray, pieces) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The sleeves' render mesh: each tube's grid with its first column repeated at the end, UVs metres of the cut
    (`pattern`, undraped): u along each ring from the arm's upper side (each ring centred on the tube's top ring's
    middle), v along the tube from its hem; the same scale for both tubes. Returns (render vertex -> simulated
    vertex (R,), faces (F, 3), uvs (R, 2), metres per UV), as `drape._pieces_render_mesh` does for the trousers."""
    from .geometry import metre_uvs, seamed_grid

    pat = np.asarray(pattern, np.float64)
    src, faces, us, vs = [], [], [], []
    n = 0
    for grid in pieces:
        cols = grid.shape[1]
        full, f, arc = seamed_grid(grid, n, pat)
        faces.append(f)
        u = 0.5 * arc[0, -1] - 0.5 * arc[:, -1:] + arc
        step = np.linalg.norm(np.diff(pat[grid].mean(1), axis=0), axis=1)  # ring centre to ring centre
        down = np.concatenate([[0.0], np.cumsum(step)])
        us.append(u.ravel())
        vs.append(np.repeat(down[-1] - down, cols + 1))
        src.append(full.ravel())
        n += full.size
    uvs, mpu = metre_uvs(us, vs)
    return np.concatenate(src), np.concatenate(faces), uvs, mpu
