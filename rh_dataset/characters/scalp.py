"""The scalp and the space around the head that hair may occupy, in the rest pose.

In: `BodyFeatures` (rest vertices, normals, bone heads, region masks), a hair style, the outermost garment offset per
body vertex. Out: `Scalp` - the skull's radius on an (azimuth, elevation) grid about a point inside the skull and
the hairline elevation per azimuth (`scalp`), and the hanging envelope of head, neck, trunk and shoulders that
hanging hair must stay outside (`hang_envelope`). Strands are grown on and around these (`hair.py`).

Angles: azimuth theta from -Y (the character's front) towards +X (its left); elevation from the horizontal plane
through the skull centre. The skull radius is a kernel regression of the head vertices' radii (ears excluded: hair
covers them), so it is smooth however coarse the scalp mesh is.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy import ndimage

from .body_features import BodyFeatures

__all__ = ["Scalp", "scalp", "hair_frame", "directions", "hang_envelope", "sample_envelope", "N_AZ", "E_DENSE"]

N_AZ = 72  # azimuth bins (5 degrees)
E_DENSE = np.radians(np.arange(90.0, -70.0, -2.0))  # elevations the skull profile is sampled at (descending)
# How far below the eyes the hairline runs at the nape, metres relative to the head bone.
_NAPE = {"buzz": -0.03, "short": -0.04, "bob": -0.05, "long": -0.05, "long_wavy": -0.05, "bun": -0.035,
         "ponytail": -0.035}


def hair_frame(feats: BodyFeatures) -> tuple[np.ndarray, float]:
    """Centre of the skull (the scalp's polar origin) and the eyes' height."""
    hb = feats.bone_heads["head"]
    z_eye = 0.5 * float(feats.bone_heads["eye.L"][2] + feats.bone_heads["eye.R"][2])
    return np.array([hb[0], hb[1] + 0.005, z_eye - 0.005]), z_eye


def directions(theta: np.ndarray, elev: np.ndarray) -> np.ndarray:
    """Unit vectors (..., 3) for azimuth theta and elevation elev (radians, broadcast)."""
    ce = np.cos(elev)
    return np.stack(np.broadcast_arrays(np.sin(theta) * ce, -np.cos(theta) * ce, np.sin(elev)), axis=-1)


@dataclasses.dataclass(frozen=True)
class Scalp:
    """centre (3,); z_eye; radius (N_AZ, len(E_DENSE)) metres on azimuths -180 + 5 k degrees and E_DENSE;
    hairline (N_AZ,) elevation of the hairline per azimuth (radians)."""

    centre: np.ndarray
    z_eye: float
    radius: np.ndarray
    hairline: np.ndarray

    def _coords(self, theta: np.ndarray, elev: np.ndarray):
        a = (np.degrees(theta) + 180.0) / (360.0 / N_AZ)
        e = (np.degrees(E_DENSE[0]) - np.degrees(elev)) / 2.0
        return a, e

    def radius_at(self, theta: np.ndarray, elev: np.ndarray) -> np.ndarray:
        """Skull radius (bilinear, azimuth wrapping) at angles of any shape."""
        a, e = self._coords(np.asarray(theta), np.asarray(elev))
        pad = np.concatenate([self.radius, self.radius[:1]], 0)
        a = np.mod(a, N_AZ)
        return ndimage.map_coordinates(pad, [a.ravel(), e.ravel()], order=1, mode="nearest").reshape(a.shape)

    def hairline_at(self, theta: np.ndarray) -> np.ndarray:
        a = np.mod((np.degrees(np.asarray(theta)) + 180.0) / (360.0 / N_AZ), N_AZ)
        pad = np.concatenate([self.hairline, self.hairline[:1]])
        return np.interp(a, np.arange(N_AZ + 1), pad)


def _skull_radius(feats: BodyFeatures, centre: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Radius of the head surface along unit `dirs` (..., 3): a Gaussian kernel regression (sigma ~6 degrees) of the
    outward-facing head/neck vertices' distances from `centre`, ears excluded."""
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
    nape = _NAPE[style]
    knots = np.array([0.0, 25.0, 45.0, 62.0, 78.0, 92.0, 108.0, 122.0, 140.0, 180.0])
    heights = np.array([z_eye + 0.05, z_eye + 0.052, z_eye + 0.046, z_eye + 0.03, z_eye + 0.0, z_eye + 0.02,
                        z_eye + 0.012, hb[2] + 0.0, hb[2] + 0.85 * nape, hb[2] + nape])
    return np.interp(np.abs(np.degrees(theta)), knots, heights)


def scalp(style: str, feats: BodyFeatures) -> Scalp:
    """The skull profile and the style's hairline (smooth in azimuth)."""
    centre, z_eye = hair_frame(feats)
    theta = np.radians(-180.0 + 360.0 * np.arange(N_AZ) / N_AZ)
    tt, ee = np.meshgrid(theta, E_DENSE, indexing="ij")
    r = _skull_radius(feats, centre, directions(tt, ee))
    z = centre[2] + r * np.sin(ee)
    line = _hairline_height(style, feats, theta)
    e_h = np.empty(N_AZ)
    for a in range(N_AZ):
        below = np.flatnonzero(z[a] < line[a])
        k = max(int(below[0]) if len(below) else len(E_DENSE) - 1, 1)
        z0, z1 = z[a, k - 1], z[a, k]
        f = float(np.clip((z0 - line[a]) / max(z0 - z1, 1e-9), 0.0, 1.0))
        e_h[a] = E_DENSE[k - 1] + f * (E_DENSE[k] - E_DENSE[k - 1])
    e_h = ndimage.gaussian_filter1d(e_h, 1.2, mode="wrap")
    return Scalp(centre=centre, z_eye=float(z_eye), radius=r, hairline=e_h)


def _body_cylinder(feats: BodyFeatures, under: np.ndarray, centre: np.ndarray, z_lo: float, z_hi: float,
                   dz: float, groups: tuple[str, ...] = ("head", "neck", "torso", "shoulder")):
    """Per (azimuth bin, height bin) the largest horizontal distance from the head's vertical axis of the body's
    `groups` (head, neck, trunk and shoulders; clothes included)."""
    m = feats.in_groups(*groups)
    p = feats.rest_vertices[m] + under[m, None] * feats.rest_normals[m]
    rel = p[:, :2] - centre[:2]
    az = np.degrees(np.arctan2(rel[:, 0], -rel[:, 1])) % 360.0
    rho = np.hypot(rel[:, 0], rel[:, 1])
    zs = np.arange(z_hi, z_lo - dz, -dz)  # top down
    ai = np.floor(az / (360.0 / N_AZ)).astype(np.int64) % N_AZ
    zi = np.round((z_hi - p[:, 2]) / dz).astype(np.int64)
    ok = (zi >= 0) & (zi < len(zs))
    grid = np.zeros((N_AZ, len(zs)))
    np.maximum.at(grid, (ai[ok], zi[ok]), rho[ok])
    return ndimage.maximum_filter(grid, size=(3, 3), mode=("wrap", "nearest")), zs


def hang_envelope(feats: BodyFeatures, under: np.ndarray, z_lo: float, z_hi: float, clear: float = 0.009,
                  dz: float = 0.006, lead: int = 7, arms: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Where hanging hair may fall: per (azimuth bin of 5 degrees from the front, height bin) the smallest horizontal
    distance from the skull's vertical axis that clears head, neck, trunk, shoulders and clothes by `clear` metres,
    widened as hair falls (the running maximum downwards: hair does not tuck back under a shoulder) and starting to
    widen ~2 cm (`lead` // 2 bins; `lead` 1: only at it) above an obstacle. Returns (grid (N_AZ, Z), z of the bins,
    top down). `arms`: the upper arms are obstacles too (a scarf over the shoulders; hair leaves them a sector).
    """
    centre, _ = hair_frame(feats)
    groups = ("head", "neck", "torso", "shoulder") + (("upperarm",) if arms else ())
    grid, zs = _body_cylinder(feats, under, centre, z_lo, z_hi, dz, groups)
    need = ndimage.maximum_filter1d(grid + clear, lead, axis=1, origin=-(lead // 2), mode="nearest")
    hang = np.maximum.accumulate(need, axis=1)
    smooth = ndimage.gaussian_filter(hang, (0.8, 1.5), mode=("wrap", "nearest"))
    return np.maximum(smooth, hang), zs


def sample_envelope(grid: np.ndarray, zs: np.ndarray, az_deg: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Bilinear lookup of an (azimuth bin, z bin) grid (bin centres at (k + 0.5) * 5 degrees, wrapping)."""
    pad = np.concatenate([grid[-1:], grid, grid[:1]], 0)
    a = (np.asarray(az_deg) % 360.0) / (360.0 / N_AZ) - 0.5 + 1.0
    zi = (zs[0] - np.asarray(z)) / (zs[0] - zs[1])
    return ndimage.map_coordinates(pad, [np.ravel(a), np.ravel(zi)], order=1, mode="nearest").reshape(np.shape(z))
