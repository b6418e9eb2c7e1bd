"""Strand hair grown on anny's scalp in the rest pose, then bound to the body so it follows every pose.

In: a style name, `BodyFeatures`, the character seed's random stream, the outermost garment offset per body
vertex. Out: `StrandGeometry` - S strands of K control points each (a cubic B-spline per strand, rendered by
Mitsuba's `bsplinecurve`), a radius per control point, and every control point bound to the body the way skirts
are (`geometry.bind_points`: a convex blend of smoothed body vertices plus an offset along the blended normal).

Growth (all strands marched together, 2.5 mm steps):
- roots: directions on the sphere about the skull centre, uniform in solid angle, above the style's hairline
  (`scalp.Scalp`); each root sits on the skull (kernel-regressed radius) - deterministic from the seed;
- on the scalp, a strand follows the style's comb field projected on the skull, at a height above it that grows
  along the strand (layered volume): short styles are combed back and down, long ones part in the middle and
  sweep back over the temples (so no strand crosses the face), ponytails and buns are drawn to the tie / bun;
- hanging styles (bob, long, long_wavy) fall vertically from where they leave the skull, outside the
  `scalp.hang_envelope` of head, neck, shoulders, back and clothes; ponytails follow the tail's curve, each strand
  at a fixed place in its cross-section; buns wrap round the bun;
- then waves (outward only), clumping towards the guide strand nearest along the whole strand, and frizz (both
  growing towards the tip).
The binding region is the head and neck for short styles (they move rigidly with the head) and head, neck, trunk,
shoulders and upper arms for hanging ones (they bend with the neck and shoulders). Posed, control points that an arm
or the trunk took under the skin below the neck are put back outside it (`push_out_of_body`).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from rh_common.body_model import ANNY_TOPOLOGY

from .body_features import BodyFeatures
from .geometry import bind_points, faces_in_box, smoothstep, surface_clearance
from .scalp import Scalp, directions, hang_envelope, sample_envelope, scalp

__all__ = ["StrandStyle", "STRAND_STYLES", "StrandGeometry", "build_hair", "STEP", "push_out_of_body", "PUSHED_GROUPS",
           "BODY_CLEARANCE"]

STEP = 0.0025  # metres per growth step
_BLEND_KEEP = 16  # blend weights kept per control point (the largest; renormalised)
_ARM_SECTOR = (55.0, 125.0)  # degrees of azimuth from the front that hanging hair leaves to the arms


@dataclasses.dataclass(frozen=True)
class StrandStyle:
    """n_strands: strands at density 1 (each stands for a wisp of real hairs); points: control points per strand;
    length: (min, max) metres on the scalp (short styles; hanging ones end at their hem); lift: metres the top
    layer stands off the skull; radius: metres at the root (tapering to 40 % at the tip); clump: how far tips are
    pulled to their clump's guide in [0, 1]; frizz: metres of random tip displacement; wave: amplitude (metres)
    and period of waves; hangs: falls below the skull."""

    n_strands: int
    points: int
    length: tuple[float, float]
    lift: float
    radius: float
    clump: float
    frizz: float
    wave: float = 0.0
    wave_period: float = 0.06
    hangs: bool = False


STRAND_STYLES = {
    "buzz": StrandStyle(9000, 4, (0.004, 0.007), 0.001, 0.0005, 0.0, 0.0005),
    "short": StrandStyle(5000, 7, (0.045, 0.08), 0.012, 0.001, 0.3, 0.002),
    "bob": StrandStyle(4500, 10, (0.3, 0.3), 0.012, 0.001, 0.35, 0.003, hangs=True),
    "long": StrandStyle(4500, 20, (0.6, 0.6), 0.01, 0.001, 0.4, 0.004, hangs=True),
    "long_wavy": StrandStyle(4500, 26, (0.6, 0.6), 0.012, 0.001, 0.5, 0.005, wave=0.012, wave_period=0.1,
                             hangs=True),
    "ponytail": StrandStyle(4000, 20, (0.5, 0.5), 0.004, 0.001, 0.3, 0.003),
    "bun": StrandStyle(4000, 16, (0.5, 0.5), 0.004, 0.001, 0.2, 0.001),
}


@dataclasses.dataclass(frozen=True)
class StrandGeometry:
    """S strands x K control points. rest (S, K, 3) the designed rest-pose points; radius (S, K) metres;
    blend_vertices (S*K, B) int32 / blend_weights (S*K, B) float32 (rows sum to 1) / offset (S*K,) float32: the
    binding (point = sum w v + offset * normalise(sum w n) over posed body vertices and normals)."""

    style: str
    rest: np.ndarray
    radius: np.ndarray
    blend_vertices: np.ndarray
    blend_weights: np.ndarray
    offset: np.ndarray

    @property
    def n_strands(self) -> int:
        return int(self.rest.shape[0])


def _roots(sc: Scalp, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """n root angles (theta, elev) uniform in solid angle above the hairline (rejection from the sphere)."""
    th, el = [], []
    while sum(len(t) for t in th) < n:
        m = 4 * n
        t = rng.uniform(-np.pi, np.pi, m)
        e = np.arcsin(rng.uniform(-0.6, 1.0, m))
        ok = e > sc.hairline_at(t)
        th.append(t[ok])
        el.append(e[ok])
    return np.concatenate(th)[:n], np.concatenate(el)[:n]


def _angles(rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = np.linalg.norm(rel, axis=-1)
    return np.arctan2(rel[..., 0], -rel[..., 1]), np.arcsin(np.clip(rel[..., 2] / np.maximum(r, 1e-12), -1, 1))


def _comb(style: str, rel: np.ndarray, theta: np.ndarray, side: np.ndarray, target: np.ndarray | None):
    """The direction (unnormalised, (N, 3)) each strand is combed in at its current point (head frame)."""
    n = len(rel)
    if target is not None:
        return target - rel
    if style in ("buzz", "short"):
        return np.stack([0.35 * side, np.full(n, 0.7), np.full(n, -0.6)], 1)
    front = smoothstep((np.radians(80.0) - np.abs(theta)) / np.radians(35.0))
    return np.stack([side * (0.3 + 1.3 * front), 0.25 + 0.5 * front, -1.0 + 0.95 * front], 1)


def _tail(sc: Scalp, feats: BodyFeatures, under: np.ndarray):
    """The ponytail's axis (T, 3), its radius profile (T,) and a frame (side, nrm) per sample, off the neck/back."""
    e_t = np.radians(8.0)
    out = directions(np.array(np.pi), np.array(e_t))
    tie = sc.centre + (float(sc.radius_at(np.pi, e_t)) + 0.004) * out
    s = np.linspace(0.0, 1.0, 60)
    p0, p1 = tie - 0.006 * out, tie + 0.07 * out + np.array([0.0, 0.0, 0.01])
    p2 = p1 + np.array([0.0, 0.03, -0.3])
    curve = ((1 - s) ** 2)[:, None] * p0 + (2 * (1 - s) * s)[:, None] * p1 + (s ** 2)[:, None] * p2
    radius = np.interp(s, [0.0, 0.05, 0.09, 0.25, 0.7, 1.0], [0.010, 0.010, 0.016, 0.019, 0.012, 0.004])
    cand = np.flatnonzero(feats.in_groups("head", "neck", "torso", "shoulder"))
    vb = feats.rest_vertices + under[:, None] * feats.rest_normals
    for _ in range(4):  # shift the tail backwards where its outline would come closer than 6 mm to the back
        h = surface_clearance(curve, vb, feats.rest_normals, cand) - radius
        need = np.where(s < 0.15, 0.0, np.maximum(0.006 - h, 0.0))
        if not need.any():
            break
        curve = curve + np.maximum.accumulate(1.3 * need)[:, None] * np.array([0.0, 1.0, 0.0])
    tang = np.gradient(curve, axis=0)
    tang /= np.linalg.norm(tang, axis=1, keepdims=True)
    side = np.cross(tang, [0.0, 1.0, 0.0])
    side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-9)
    return curve, radius, side, np.cross(side, tang)


def _bun(sc: Scalp):
    """Bun centre, radius and frame (out, b1, b2): an ellipsoid at the back of the crown."""
    e_b = np.radians(42.0)
    out = directions(np.array(np.pi), np.array(e_b))
    rb = 0.4 * float(np.median(sc.radius))
    c = sc.centre + (float(sc.radius_at(np.pi, e_b)) + 0.8 * rb + 0.002) * out  # inner pole on the scalp
    b1 = np.cross(out, [0.0, 0.0, 1.0])
    b1 /= np.linalg.norm(b1)
    return c, rb, out, b1, np.cross(out, b1)


def _grow(style: str, st: StrandStyle, sc: Scalp, feats: BodyFeatures, under: np.ndarray,
          rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Polylines (one (M_i, 3) array per strand) in the rest pose."""
    c = sc.centre
    theta, elev = _roots(sc, n, rng)
    side = np.sign(np.sin(theta) + rng.normal(0.0, 0.04, n))  # a centre parting, slightly irregular
    lift_top = st.lift * rng.uniform(0.25, 1.0, n) ** 0.7  # each strand's own layer height
    length = rng.uniform(*st.length, n)
    rel = (sc.radius_at(theta, elev) + 0.0008)[:, None] * directions(theta, elev)
    mode = np.zeros(n, np.int8)  # 0 on the scalp, 1 hanging, 2 tail / bun wrap, 3 done
    arc = np.zeros(n)
    target = tail = None
    if style == "ponytail":
        curve, trad, tside, tnrm = _tail(sc, feats, under)
        phi, rr = rng.uniform(0, 2 * np.pi, n), np.sqrt(rng.uniform(0.0, 1.0, n))
        prof = (np.cos(phi) * rr)[:, None, None] * tside + (0.8 * np.sin(phi) * rr)[:, None, None] * tnrm
        tail = curve[None] - c + trad[None, :, None] * prof  # (n, T, 3) every strand's own path down the tail
        target = tail[:, 0]
        tail_len = float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum())
    elif style == "bun":
        bc, rb, bout, b1, b2 = _bun(sc)
        lon0 = rng.uniform(0, 2 * np.pi, n)
        turns = rng.uniform(0.8, 1.6, n)
        shell = rng.uniform(0.85, 1.0, n)

        def bun_at(t):  # t in [0, 1]: from the inner pole (at the head) round the bun to its outer pole
            lat = np.pi * (1.0 - 0.92 * t)
            lon = lon0 + 2 * np.pi * turns * t
            loc = np.stack([0.8 * np.cos(lat), np.sin(lat) * np.cos(lon), np.sin(lat) * np.sin(lon)], 1)
            loc = loc * (rb * shell)[:, None]
            return bc - c + loc[:, :1] * bout + loc[:, 1:2] * b1 + loc[:, 2:] * b2
        target = bun_at(np.zeros(n)) + 0.0 * rel
        bun_len = np.pi * rb * (1.0 + turns)
    if st.hangs:
        z_hem = sc.z_eye - 0.1 if style == "bob" else float(feats.bone_heads["spine02"][2]) + 0.03
        env, zs = hang_envelope(feats, under, z_hem - 0.12, c[2] + 0.12)
        z_sh = 0.5 * float(feats.bone_heads["shoulder01.L"][2] + feats.bone_heads["shoulder01.R"][2])
        th_deg = np.degrees(theta)
        hem = z_hem + rng.normal(0.0, 0.006, n) + (0.012 if style == "bob" else -0.05) * np.cos(np.radians(th_deg)
                                                                                               ) ** 2
    paths = [rel.copy()]
    phase = rng.uniform(0, 2 * np.pi, n)
    t_wrap = np.zeros(n)
    z_start, rho_base, az_base = np.zeros(n), np.zeros(n), np.zeros(n)
    for _ in range(2000):
        if np.all(mode == 3):
            break
        p = rel.copy()
        th, el = _angles(rel)
        on = mode == 0
        if on.any():
            u = rel[on] / np.linalg.norm(rel[on], axis=1, keepdims=True)
            g = _comb(style, rel[on], th[on], side[on], None if target is None else target[on])
            t = g - (g * u).sum(1, keepdims=True) * u
            t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
            d = u + t * (STEP / np.linalg.norm(rel[on], axis=1, keepdims=True))
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            tn, en = _angles(d)
            a_on = arc[on] + STEP
            h = 0.0015 + lift_top[on] * smoothstep(a_on / 0.05)
            p[on] = (sc.radius_at(tn, en) + h)[:, None] * d
            idx = np.flatnonzero(on)
            if st.hangs:
                leave = en < np.radians(-4.0)
                lv = idx[leave]
                mode[lv] = 1
                z_start[lv] = p[lv, 2]
                rho_base[lv] = np.hypot(p[lv, 0], p[lv, 1])
                az_base[lv] = np.degrees(np.arctan2(p[lv, 0], -p[lv, 1]))
            elif target is not None:
                # Reached when over the target on the scalp (within 1 cm across): a target under the strand's layer
                # is never within 1 cm, and such a strand would circle above it until the loop ends.
                r_p = np.linalg.norm(p[on], axis=1, keepdims=True)
                u_t = target[on] / np.linalg.norm(target[on], axis=1, keepdims=True)
                near = np.linalg.norm(p[on] / r_p - u_t, axis=1) * r_p[:, 0] < 0.01
                mode[idx[near]] = 2
            else:
                stop = (a_on >= length[on]) | (en < sc.hairline_at(tn) - 0.12)
                mode[idx[stop]] = 3
        hang = mode == 1
        if hang.any():
            z = rel[hang, 2] - STEP
            # Hair at the sides goes in front of or behind the shoulder before it gets there: the arms (outside
            # the envelope, which would otherwise tent over them) take the sector ~55-125 degrees from the front.
            ab = az_base[hang]
            aa = np.abs(ab)
            blocked = (aa > _ARM_SECTOR[0]) & (aa < _ARM_SECTOR[1])
            to = np.sign(ab) * np.where(aa < 90.0, _ARM_SECTOR[0], _ARM_SECTOR[1])
            pull = blocked * smoothstep((z_sh + 0.1 - (z + c[2])) / 0.1)
            az = ab + (to - ab) * pull
            rho = np.maximum(rho_base[hang], sample_envelope(env, zs, az % 360.0, z + c[2]) + 0.6 * lift_top[hang])
            rho_base[hang] = rho
            if st.wave > 0:  # waves: outward only, growing in over 5 cm
                ramp = smoothstep((z_start[hang] - z) / 0.05)
                rho_w = rho + st.wave * ramp * 0.5 * (1 + np.sin(2 * np.pi * z / st.wave_period + phase[hang]))
                az = az + np.degrees(st.wave * ramp * np.cos(2 * np.pi * z / st.wave_period + phase[hang]) / rho)
            else:
                rho_w = rho
            a = np.radians(az)
            p[hang] = np.stack([rho_w * np.sin(a), -rho_w * np.cos(a), z], 1)
            done = z + c[2] < hem[hang]
            mode[np.flatnonzero(hang)[done]] = 3
        wrap = mode == 2
        if wrap.any():
            iw = np.flatnonzero(wrap)
            if style == "ponytail":
                t_wrap[iw] += STEP / tail_len
                k = np.minimum(t_wrap[iw] * (tail.shape[1] - 1), tail.shape[1] - 1.0001)
                k0 = np.floor(k).astype(int)
                f = (k - k0)[:, None]
                p[iw] = tail[iw, k0] * (1 - f) + tail[iw, k0 + 1] * f
            else:
                t_wrap[iw] += STEP / bun_len[iw]
                p[iw] = bun_at(np.minimum(t_wrap, 1.0))[iw]
            mode[iw[t_wrap[iw] >= 1.0]] = 3
        moved = mode != 3
        arc = arc + np.where(moved, np.linalg.norm(p - rel, axis=1), 0.0)
        rel = np.where(moved[:, None], p, rel)
        paths.append(np.where(moved[:, None], p, np.nan))
    P = np.stack(paths, 1) + c  # (n, M, 3), NaN after a strand ended
    return [P[i][np.isfinite(P[i, :, 0])] for i in range(n)]


def _resample(lines: list[np.ndarray], k: int) -> np.ndarray:
    """Each polyline at k points equally spaced in arc length."""
    out = np.empty((len(lines), k, 3))
    u = np.linspace(0.0, 1.0, k)
    for i, line in enumerate(lines):
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))])
        s = s / max(s[-1], 1e-9)
        for d in range(3):
            out[i, :, d] = np.interp(u, s, line[:, d])
    return out


def _clump_and_frizz(pts: np.ndarray, st: StrandStyle, rng: np.random.Generator, centre: np.ndarray) -> np.ndarray:
    s, k = pts.shape[:2]
    w = smoothstep(np.linspace(-0.2, 1.0, k) / 1.0)[None, :, None]  # roots untouched, tips most
    if st.clump > 0:
        n_guides = max(s // 25, 1)
        guides = rng.choice(s, n_guides, replace=False)
        # A strand joins the guide that runs closest to it along its whole length, not the one rooted nearest: two
        # neighbouring roots may part round a shoulder, and pulling one towards the other put tips inside the arm
        # (long hair 48 mm deep before, tests/test_hair.py).
        _, g = cKDTree(pts[guides].reshape(n_guides, -1)).query(pts.reshape(s, -1))
        pts = pts + st.clump * w * (pts[guides[g]] - pts)
    if st.frizz > 0:
        jit = rng.normal(0.0, st.frizz, pts.shape) * w ** 2
        out = pts - centre
        out[..., 2] = 0.0
        out /= np.maximum(np.linalg.norm(out, axis=-1, keepdims=True), 1e-9)
        radial = (jit * out).sum(-1, keepdims=True)
        pts = pts + jit - radial * out + np.abs(radial) * out  # radial part outwards only
    return pts


def _bind(pts: np.ndarray, feats: BodyFeatures, region: np.ndarray, under: np.ndarray, smooth: float):
    b = bind_points(pts, region, feats, smooth_radius=smooth)
    keep = np.argsort(-b.blend_weights, axis=1, kind="stable")[:, :_BLEND_KEEP]
    bv = np.take_along_axis(b.blend_vertices, keep, 1)
    bw = np.take_along_axis(b.blend_weights, keep, 1).astype(np.float64)
    bw /= bw.sum(1, keepdims=True)
    v, n = feats.rest_vertices, feats.rest_normals
    base = (v[bv] * bw[..., None]).sum(1)
    nb = (n[bv] * bw[..., None]).sum(1)
    nb /= np.maximum(np.linalg.norm(nb, axis=1, keepdims=True), 1e-12)
    off = np.maximum(((pts - base) * nb).sum(1), 0.0)
    # Where the (pruned) binding cannot reproduce a point exactly, keep it 1.5 mm clear of skin and clothes.
    cand = np.flatnonzero(feats.in_groups("head", "neck", "torso", "shoulder", "upperarm"))
    surf = v + under[:, None] * n
    for _ in range(4):
        h = surface_clearance(base + off[:, None] * nb, surf, n, cand)
        need = np.maximum(0.0015 - h, 0.0)
        if not need.any():
            break
        off += 1.2 * need
    return bv.astype(np.int32), bw.astype(np.float32), off.astype(np.float32)


def build_hair(style: str, feats: BodyFeatures, rng: np.random.Generator, topology: str = ANNY_TOPOLOGY,
               under: np.ndarray | None = None, density: float = 1.0, press=None) -> StrandGeometry | None:
    """Grow and bind a style's strands (deterministic for a given `rng` state). `under` (V,) is the outermost
    garment offset per body vertex (hair stays outside it); `density` scales the strand count. `press`, if given,
    maps the grown rest-pose strands (S, K, 3) and the skull (`scalp.Scalp`) to (points, keep (S,) bool) before
    they are bound (headwear pressing and hiding hair, `headwear.press_hair`); None when no strand is left."""
    if topology != ANNY_TOPOLOGY:
        raise ValueError(f"build_hair: only {ANNY_TOPOLOGY!r} is supported")
    if style not in STRAND_STYLES:
        raise ValueError(f"build_hair: unknown style {style!r}; styles: {sorted(STRAND_STYLES)}")
    st = STRAND_STYLES[style]
    under = np.zeros(len(feats.rest_vertices)) if under is None else under
    sc = scalp(style, feats)
    n = max(int(round(st.n_strands * float(density))), 1)
    lines = _grow(style, st, sc, feats, under, rng, n)
    pts = _clump_and_frizz(_resample(lines, st.points), st, rng, sc.centre)
    taper = 1.0 - 0.6 * np.linspace(0.0, 1.0, st.points) ** 2
    radius = st.radius * rng.uniform(0.8, 1.2, (n, 1)) * taper[None, :]
    if press is not None:
        pts, keep = press(pts, sc)
        if not keep.any():
            return None
        pts, radius = pts[keep], radius[keep]
    short = style in ("buzz", "short", "bun")
    groups = ("head", "neck") if short else ("head", "neck", "torso", "shoulder", "upperarm")
    region = np.flatnonzero(feats.in_groups(*groups))
    bv, bw, off = _bind(pts.reshape(-1, 3), feats, region, under, 0.02 if short else 0.035)
    return StrandGeometry(style=style, rest=pts.astype(np.float32), radius=radius.astype(np.float32),
                          blend_vertices=bv, blend_weights=bw, offset=off)



# Posed strands are kept out of the body below the neck (`push_out_of_body`): BODY_CLEARANCE off the skin of these
# bone groups where a control point came under it. Head and neck are left out: roots sit on the scalp, and a strand
# leaving it may dip a millimetre or two under the skin between its control points by design (tests/test_hair.py).
PUSHED_GROUPS = ("torso", "shoulder", "upperarm", "lowerarm", "hand", "upperleg", "lowerleg", "foot")
BODY_CLEARANCE = 0.002  # metres
_UNDER_TANGENT = 0.0005  # metres over the nearest vertex's tangent plane below which a point is looked at exactly
_REACH = 0.05  # metres around the looked-at points in which skin is searched (deeper than a point lies in a limb)


def push_out_of_body(points: np.ndarray, vertices: np.ndarray, normals: np.ndarray, faces: np.ndarray,
                     pushed_faces: np.ndarray, clearance: float = BODY_CLEARANCE) -> np.ndarray:
    """Posed strands' control points (P, 3) that lie under the posed skin (`vertices`, `normals`, `faces`) where the
    nearest skin is one of `pushed_faces` ((F,) bool over `faces`: PUSHED_GROUPS'), put back `clearance` off it
    (`drape.push_out` over the whole body, so a point taken out of an arm pressed against the trunk does not land in
    the trunk). Why: hanging hair is bound to head, neck, trunk, shoulders and upper arms (`build_hair`), not
    simulated; an arm swinging forward or back (a reach, a walk) passed through the strands hanging over it, and a
    trunk bent or turned under the neck took strands lying on the chest into it (6 December: up to 21 mm deep,
    tests/test_hair.py). At rest no control point lies under that skin (the binding keeps them 1.5 mm off), so rest
    frames, and every point not moved, keep their bits. Only points within _UNDER_TANGENT of their nearest body
    vertex's tangent plane, or under it, are looked at exactly."""
    from .drape import closest_on_surface, push_out

    p = np.array(points, np.float64)  # a copy: the caller's points are not moved in place
    v = np.asarray(vertices, np.float64)
    n = np.asarray(normals, np.float64)
    f = np.asarray(faces)
    nearest = cKDTree(v).query(p)[1]
    pushed_vertices = np.zeros(len(v), bool)
    pushed_vertices[f[pushed_faces].ravel()] = True
    cand = np.flatnonzero((((p - v[nearest]) * n[nearest]).sum(1) < _UNDER_TANGENT) & pushed_vertices[nearest])
    if not len(cand):
        return p
    near = faces_in_box(v, f, p[cand].min(0) - _REACH, p[cand].max(0) + _REACH)
    depth, _, _, tri = closest_on_surface(v, f[near], p[cand], n, triangles=True)
    inside = cand[(depth > 0.0) & pushed_faces[near][tri]]
    if len(inside):
        p[inside] = push_out(p[inside], v, n, f, clearance)
    return p
