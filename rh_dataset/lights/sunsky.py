"""Baking Mitsuba's `sunsky` emitter into an equirectangular map, so that rendering and SH use the same light.

Mitsuba 3.9.1's `sunsky` (Hosek–Wilkie sky + a uniform sun disc of angular diameter `sun_aperture`, 0.5358°) has
+Z up in its local frame (measured: the sky is zero for directions with z < 0), so with the default identity
`to_world` its frame is our world frame. `sun_direction` is ``(cos e cos a, cos e sin a, sin e)`` for azimuth a
(counter-clockwise from +X seen from above, the same φ as ARCHITECTURE.md) and elevation e.

The bake:
* sky (``sun_scale = 0``): the emitter evaluated at each pixel centre (the sky is smooth at pixel scale);
* sun (``sky_scale = 0``): its irradiance at normal incidence ``∫_disc L dω`` by an equal-solid-angle ring
  quadrature over the disc, deposited into the one pixel that contains the sun direction as radiance
  ``E_sun / Ω_pixel``. Point-sampling the disc would catch or miss the sun depending on where pixel centres fall
  (the disc, 6.9e-5 sr, is ~1.8 equator pixels of a 1024x512 map, 3.8e-5 sr each).
So the baked sun keeps its power and colour exactly, is displaced by at most half a pixel (0.18° at 1024 wide),
and, being one pixel (bilinearly interpolated by Mitsuba), is a slightly larger source than the true 0.54° disc:
shadows are marginally softer.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from rh_common import sh

from .mitsuba_env import eval_emitter, vectorised_variant

__all__ = ["SUN_APERTURE_DEG", "SUNSKY_BAKE_HEIGHT", "sun_direction", "bake_sunsky"]

SUN_APERTURE_DEG = 0.5358  # Mitsuba's default, passed explicitly so the bake does not depend on the default
SUNSKY_BAKE_HEIGHT = 512  # same resolution as the bundled HDRIs (1024 x 512)


def sun_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit world direction towards the sun (+Z up, azimuth counter-clockwise from +X)."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def _disc_directions(centre: np.ndarray, half_angle: float, rings: int = 64, per_ring: int = 8):
    # Rings of equal solid angle (midpoints in cos ρ), so a uniform disc is integrated exactly and no sample
    # lands on the disc edge.
    helper = np.array([1.0, 0.0, 0.0]) if abs(centre[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(centre, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(centre, t1)
    cmin = math.cos(half_angle)
    cos_r = 1.0 - (np.arange(rings) + 0.5) / rings * (1.0 - cmin)
    sin_r = np.sqrt(1.0 - cos_r**2)
    psi = (np.arange(per_ring) + 0.5) * (2.0 * math.pi / per_ring)
    cr, sr = cos_r[:, None, None], sin_r[:, None, None]
    dirs = cr * centre + sr * (np.cos(psi)[None, :, None] * t1 + np.sin(psi)[None, :, None] * t2)
    weight = 2.0 * math.pi * (1.0 - cmin) / (rings * per_ring)
    return dirs.reshape(-1, 3), weight


@functools.lru_cache(maxsize=4)
def _bake_cached(azimuth_deg: float, elevation_deg: float, turbidity: float, height: int) -> np.ndarray:
    H, W = height, 2 * height
    d_sun = sun_direction(azimuth_deg, elevation_deg)
    common = {"type": "sunsky", "sun_direction": d_sun.tolist(), "turbidity": float(turbidity),
              "sun_aperture": SUN_APERTURE_DEG}
    with vectorised_variant() as mi:
        sky = mi.load_dict({**common, "sun_scale": 0.0})
        sun = mi.load_dict({**common, "sky_scale": 0.0})
        radiance = eval_emitter(mi, sky, sh.equirect_directions(H, W).reshape(-1, 3)).reshape(H, W, 3)
        dirs, w = _disc_directions(d_sun, math.radians(SUN_APERTURE_DEG) / 2.0)
        e_sun = eval_emitter(mi, sun, dirs).sum(axis=0) * w  # (3,) irradiance at normal incidence
    if not (np.all(np.isfinite(radiance)) and np.all(np.isfinite(e_sun))):
        raise ValueError(f"sunsky bake produced NaN/Inf (azimuth {azimuth_deg}, elevation {elevation_deg}, "
                         f"turbidity {turbidity})")
    phi = math.atan2(d_sun[1], d_sun[0])
    i = int(math.floor((0.5 - phi / (2.0 * math.pi)) * W)) % W
    j = min(int(math.floor(math.acos(max(-1.0, min(1.0, d_sun[2]))) / math.pi * H)), H - 1)
    radiance[j, i] += e_sun / sh.pixel_solid_angles(H, W)[j, i]
    out = np.ascontiguousarray(np.maximum(radiance, 0.0), dtype=np.float32)
    out.setflags(write=False)
    return out


def bake_sunsky(sun_azimuth_deg: float, sun_elevation_deg: float, turbidity: float,
                height: int = SUNSKY_BAKE_HEIGHT) -> np.ndarray:
    """Mitsuba's sunsky radiance as an equirectangular map (height, 2·height, 3) float32 in the world frame.

    Read-only (cached: a pure function of its arguments). See the module docstring for how the sun is baked.
    """
    return _bake_cached(float(sun_azimuth_deg), float(sun_elevation_deg), float(turbidity), int(height))
