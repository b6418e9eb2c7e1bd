"""The bridge between our equirectangular convention and Mitsuba 3's `envmap` / `sunsky` emitters.

What Mitsuba's `envmap` does (measured with Mitsuba 3.9.1, checked by tests/test_lights.py):
* local frame +Y up; a local direction v maps to texture coordinates ``u = atan2(v.x, −v.z)/2π`` (wrapped),
  ``t = arccos(v.y)/π``; ``to_world`` maps local to world directions.
* it interpolates the bitmap **bilinearly**; column i is centred at ``u = (i + 0.5)/W`` (periodic), but row k of an
  N-row bitmap sits at ``θ = πk/(N − 1)`` (rows at the poles, not at cell centres).

Our convention (ARCHITECTURE.md) puts row j's centre at ``θ = (j + 0.5)π/H``. To make Mitsuba render exactly our
map, the bitmap handed to it has ``2H + 1`` rows: row ``2j + 1`` is our row j (θ = (2j+1)π/2H, our centre), row
``2j`` is the mean of our rows j−1 and j (the midpoint of the linear segment between them), rows 0 and 2H repeat
our first and last rows. Mitsuba's bilinear lookup of that bitmap equals the bilinear interpolation of our
pixel-centre samples (periodic in u, constant from the outermost row centres to the poles): at every pixel centre
it returns our pixel value, with no resampling of the data.

The axes: with ``to_world = Rz(rotation) @ B``, ``B = [[0,0,1],[1,0,0],[0,1,0]]`` (local +Z → world +X,
local +X → world +Y, local +Y → world +Z), Mitsuba's ``u`` equals ``0.5 − φ/2π`` with ``φ = atan2(y, x)`` in the
light's frame, i.e. our mapping.
"""
from __future__ import annotations

import contextlib
import math
from typing import Any, Iterator

import numpy as np

from ..variant import DEFAULT_VARIANT, ensure_variant

__all__ = [
    "ENVMAP_BASIS",
    "rotation_z",
    "envmap_to_world",
    "mitsuba_envmap_array",
    "mitsuba_envmap_data",
    "vectorised_variant",
    "eval_emitter",
]

# Mitsuba envmap local frame (+Y up) → our world frame (+Z up); a cyclic permutation, det +1.
ENVMAP_BASIS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
ENVMAP_BASIS.setflags(write=False)


def rotation_z(rotation_deg: float) -> np.ndarray:
    """3x3 rotation about +Z by `rotation_deg`, counter-clockwise seen from above (ARCHITECTURE.md)."""
    a = math.radians(rotation_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def envmap_to_world(rotation_deg: float) -> np.ndarray:
    """4x4 `to_world` for Mitsuba's envmap: our mapping, environment rotated about +Z by `rotation_deg`."""
    T = np.eye(4)
    T[:3, :3] = rotation_z(rotation_deg) @ ENVMAP_BASIS
    return T


def mitsuba_envmap_array(radiance: np.ndarray) -> np.ndarray:
    """Our (H, W, 3) map → the (2H+1, W, 3) float32 bitmap that Mitsuba's envmap renders as exactly our map."""
    L = np.asarray(radiance, dtype=np.float32)
    H, W, C = L.shape
    out = np.empty((2 * H + 1, W, C), dtype=np.float32)
    out[1::2] = L
    out[2:-1:2] = 0.5 * (L[:-1] + L[1:])
    out[0] = L[0]
    out[-1] = L[-1]
    return out


def mitsuba_envmap_data(radiance: np.ndarray) -> np.ndarray:
    """The (2H+1, W+2, 3) float32 array Mitsuba 3.9 stores as the envmap's traversable `data` parameter.

    Mitsuba pads its bitmap with one wrapped column on each side (last column first, first column last); use
    this, not `mitsuba_envmap_array`, to swap maps through `mi.traverse(scene)[...'data']` + `params.update()`.
    """
    A = mitsuba_envmap_array(radiance)
    return np.ascontiguousarray(np.concatenate([A[:, -1:], A, A[:, :1]], axis=1))


@contextlib.contextmanager
def vectorised_variant() -> Iterator[Any]:
    """Yield the mitsuba module with a JIT (vectorised) variant active: the current one if it is vectorised;
    `llvm_ad_rgb` for the block if a scalar variant is active (restored afterwards); if no variant is set yet,
    `llvm_ad_rgb` is set and stays set."""
    # Mitsuba 3.9's variant_context cannot restore "no variant", so the project default stays set.
    mi = ensure_variant(DEFAULT_VARIANT)
    current = mi.variant()
    if not current.startswith("scalar"):
        yield mi
        return
    with mi.variant_context(DEFAULT_VARIANT):
        yield mi


def eval_emitter(mi: Any, emitter: Any, dirs: np.ndarray) -> np.ndarray:
    """Radiance (N, 3) float64 an environment emitter sends *from* world directions `dirs` (N, 3) toward the origin.

    Mitsuba's `Emitter.eval` takes the surface interaction's `wi` pointing from the emitter to the viewer, i.e.
    ``wi = −d`` for the direction d we look along.
    """
    import drjit as dr

    d = np.ascontiguousarray(np.asarray(dirs, dtype=np.float32).reshape(-1, 3))
    si = dr.zeros(mi.SurfaceInteraction3f, d.shape[0])
    si.wi = mi.Vector3f(-d[:, 0], -d[:, 1], -d[:, 2])
    out = np.array(emitter.eval(si), dtype=np.float64)
    return out.T if out.shape[0] == 3 and out.ndim == 2 and out.shape[1] == d.shape[0] else out.reshape(-1, 3)
