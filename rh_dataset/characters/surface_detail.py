"""Skin and cloth detail at the scale the protocol's pixels resolve (issue 17, part 4).

In: a `SkinTone`'s detail strengths (freckles, blush, veins), the body's rest-pose features, per-texel rest
positions of anny's UV layout (`textures.texel_positions`), a seeded generator. Out: `skin_detail`, a
multiplicative albedo factor (H, W, 3) float32 the skin texture is multiplied by; `knit_ribs`, the factor of a
knit garment's ribs. Both are deterministic functions of their inputs.

Scale rule. At the protocols' 512 x 512, 30 degree vertical field of view and camera fill 0.96, one pixel covers
~4.6 mm of skin at the body's distance (`bench/skin_detail.py` computes it per subject: 4.0-5.1 mm over the 49
benchmark subjects' framings). A pattern is resolved only if its features span a pixel, so detail is laid out in
metres on the body (solid noise over the rest positions, not over the UV layout, whose texel size varies) at
feature sizes >= ~4 mm: freckles of 4-6 mm (the large end of real freckles), veins ~6 mm wide, blush over
centimetres, knit ribs of 12 mm period (a resolved period needs >= 2 pixels, 9 mm). What is smaller (pores,
0.1-0.3 mm; fine wrinkles; smaller freckles; woven threads, 0.2-0.5 mm) is left out, except as the mean it gives a
pixel: the small freckles' mean darkening of a freckled region. The bench prints what leaving it in would cost.

Low contrast: every factor stays within [0.75, 1.1] per channel and the detail moves a body's mean albedo by less
than 2% (tests/test_surface_detail.py holds both).
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from .body_features import BodyFeatures
from .geometry import smoothstep

__all__ = ["solid_noise", "skin_detail", "knit_ribs", "texel_weights", "FRECKLE_CELL_M", "VEIN_CELL_M",
           "KNIT_PERIOD_M", "DETAIL_FACTOR_RANGE"]

FRECKLE_CELL_M = 0.005  # noise cell of the freckle spots: spots of ~4-6 mm
VEIN_CELL_M = 0.04  # noise cell of the venous network: the zero set of smooth noise, curves a few cm apart
VEIN_HALF_WIDTH = 0.1  # |noise| below this is on a vein: ~3-6 mm either side of the centre line at this cell size
KNIT_PERIOD_M = 0.012  # a chunky 2x2 rib: 12 mm from wale to wale
DETAIL_FACTOR_RANGE = (0.75, 1.1)  # bounds of every multiplicative factor here (low contrast)
# Multiplicative colour of each detail at full strength (linear RGB): freckles are melanin (browner, darker), blush is
# haemoglobin (redder: green and blue absorbed), veins show bluish-green through the skin (red absorbed a little).
_FRECKLE = np.array([0.80, 0.74, 0.72], dtype=np.float32)
_FRECKLE_UNRESOLVED = np.array([0.97, 0.96, 0.96], dtype=np.float32)  # mean of the sub-pixel freckles of a region
_BLUSH = np.array([1.05, 0.86, 0.88], dtype=np.float32)
_VEIN = np.array([0.90, 0.95, 1.0], dtype=np.float32)


def solid_noise(rng: np.random.Generator, positions: np.ndarray, cell_m: float, order: int = 1) -> np.ndarray:
    """Value noise in [-1, 1] over 3D space, sampled at `positions` (..., 3) metres: a random lattice of `cell_m`
    spacing covering their bounds, interpolated (order 1: trilinear; 3: a cubic B-spline, smoother and of lower
    amplitude). Features have the same metric size wherever the UV layout stretches. float32 (...)."""
    p = np.asarray(positions, dtype=np.float32)
    flat = p.reshape(-1, 3)
    lo = flat.min(0) - 2.0 * cell_m
    dims = np.ceil((flat.max(0) - lo) / cell_m).astype(int) + 3
    grid = rng.uniform(-1.0, 1.0, tuple(dims)).astype(np.float32)
    coords = ((flat - lo) / np.float32(cell_m)).T
    out = ndimage.map_coordinates(grid, coords, order=order, mode="nearest", prefilter=False)
    return out.reshape(p.shape[:-1]).astype(np.float32)


def texel_weights(vertex_mask: np.ndarray, face: np.ndarray, bary: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """A per-vertex 0/1 mask interpolated to texels (`geometry.uv_raster`'s face and barycentrics), float32 (H, W)."""
    m = vertex_mask.astype(np.float32)[faces[face]]  # (H, W, 3)
    return np.einsum("hwk,hwk->hw", m, bary.astype(np.float32))


def _face_frame(feats: BodyFeatures, pos: np.ndarray):
    """Per-texel offsets from the eyes' midpoint: lateral |dx|, height dz, and whether the texel faces forward."""
    el, er = feats.bone_heads["eye.L"], feats.bone_heads["eye.R"]
    mid = 0.5 * (el + er)
    dx = np.abs(pos[..., 0] - mid[0])
    dz = pos[..., 2] - mid[2]
    front = smoothstep((mid[1] + 0.02 - pos[..., 1]) / 0.02)  # in front of the eyes' plane (the face is at -Y)
    return dx, dz, front


def skin_detail(freckles: float, blush: float, veins: float, feats: BodyFeatures, positions: np.ndarray,
                regions: dict[str, np.ndarray], rng: np.random.Generator) -> np.ndarray:
    """The skin's multiplicative detail factor (H, W, 3) float32. `regions`: texel weights (H, W) in [0, 1] for
    "face", "lips", "arms" (upper and lower arms, shoulders), "forearms" (lower arms and hands), "feet".
    Noise is evaluated only where a pattern can appear (its region), from per-pattern generators seeded from `rng`
    first, so one strength never moves another's pattern."""
    pos = np.asarray(positions, dtype=np.float32)
    h, w = pos.shape[:2]
    # One generator per pattern, seeded first: a pattern's noise does not depend on which others are painted.
    rng_spots, rng_patches, rng_veins = (np.random.default_rng(int(k)) for k in rng.integers(0, 2**63, 3))
    factor = np.ones((h, w, 3), dtype=np.float32)
    dx, dz, front = _face_frame(feats, pos)
    face = np.clip(regions["face"], 0.0, 1.0) * (1.0 - np.clip(regions["lips"], 0.0, 1.0))

    if freckles > 0.0:
        # Density: across the nose and cheeks (a band under the eyes), less on shoulders and arms; patchy.
        mask_face = np.exp(-0.5 * ((dx / 0.035) ** 2 + ((dz + 0.025) / 0.022) ** 2)) * front * face
        density = np.maximum(mask_face, 0.5 * np.clip(regions["arms"], 0.0, 1.0))
        where = density > 0.02
        density = np.where(where, density, 0.0)
        density[where] *= np.clip(0.75 + 0.5 * solid_noise(rng_patches, pos[where], 0.05), 0.0, 1.0) * freckles
        spots = np.zeros((h, w), np.float32)
        spots[where] = solid_noise(rng_spots, pos[where], FRECKLE_CELL_M, order=3)
        # Threshold of the cubic-spline noise (std ~0.2): ~4% of texels above 0.36, ~25% above 0.13 (measured).
        spot = smoothstep((spots - (0.36 - 0.3 * density)) / 0.06) * smoothstep(density / 0.2)
        f = 1.0 + (spot[..., None] * (_FRECKLE - 1.0))
        f = f * (1.0 + density[..., None] * (_FRECKLE_UNRESOLVED - 1.0))
        factor *= f
    if blush > 0.0:
        cheeks = np.exp(-0.5 * (((dx - 0.035) / 0.017) ** 2 + ((dz + 0.03) / 0.015) ** 2))
        nose = np.exp(-0.5 * ((dx / 0.008) ** 2 + ((dz + 0.038) / 0.01) ** 2))
        b = np.clip(cheeks + 0.6 * nose, 0.0, 1.0) * front * face * blush
        factor *= 1.0 + b[..., None] * (_BLUSH - 1.0)
    if veins > 0.0:
        temples = np.exp(-0.5 * (((dx - 0.055) / 0.012) ** 2 + ((dz - 0.01) / 0.015) ** 2)) * face
        region = np.clip(np.maximum(np.maximum(regions["forearms"], regions["feet"]), temples), 0.0, 1.0)
        where = region > 0.02
        line = np.zeros((h, w), np.float32)
        n = solid_noise(rng_veins, pos[where], VEIN_CELL_M, order=3)
        line[where] = (1.0 - np.clip(np.abs(n) / VEIN_HALF_WIDTH, 0.0, 1.0)) ** 2
        v = line * region * veins
        factor *= 1.0 + v[..., None] * (_VEIN - 1.0)
    lo, hi = DETAIL_FACTOR_RANGE
    return np.clip(factor, lo, hi).astype(np.float32)


def knit_ribs(coords_m: np.ndarray) -> np.ndarray:
    """Albedo factor (H, W) float32 of a knit's ribs: the wales run up the garment, `KNIT_PERIOD_M` apart; the
    furrow between two wales is 15% darker, standing in for the self-shadowing a smooth shell cannot cast."""
    a = np.asarray(coords_m, dtype=np.float32)[..., 0]
    ridge = 0.5 + 0.5 * np.cos(2.0 * np.pi * a / KNIT_PERIOD_M)
    return (1.0 - 0.15 * (1.0 - ridge) ** 2).astype(np.float32)
