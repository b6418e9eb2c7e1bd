"""One light at a time (OLAT): a small uniform disc of light at infinity, as an equirectangular map.

In: a direction (azimuth, elevation in degrees, the world frame of every light: +Z up, azimuth counter-clockwise
from +X, so the camera of `rh_common.camera.frame_body`, on the -Y side, is at azimuth 270), an angular radius α
and a colour. Out: the (H, 2H, 3) float32 map that is zero except a cone of half-angle α around the direction
(`olat_map`), the `scale` that makes it a light of the documented strength (`olat_scale`), the named direction sets
of the olat split (`DIRECTION_SETS`, `olat_directions`) and the frame JSON record of one OLAT light (`olat_record`).

Why a map: SH (`rh_common.sh.project_equirect`), rotation, Mitsuba's envmap emitter and the exporters' baked maps
then work as for any environment (docs/ARCHITECTURE.md, "One light at a time").

The disc is antialiased by exact area: each texel's value is the fraction of its solid angle inside the cone,
integrated over 8x8 sub-cells of exact solid angle, then renormalised so that the map's solid angle is exactly the
cone's, Ω = 2π(1 − cos α). A map of unit colour c therefore has ∫L dω = c Ω, and a surface facing it (its normal at
angle β ≤ 90° − α from the axis) receives the analytic irradiance E = c π sin²α cos β (= c Ω cos β for a small
source, to (1 + cos α)/2).

Strength: `olat_scale` makes a Lambertian surface facing the light receive irradiance of luminance π, so a white
surface facing it has radiance (luminance) 1, as under a uniform environment of unit radiance; the frame's display
exposure is π / luminance(E_facing) (rh_dataset.generate.frames.exposure_for), 1 for a light at this scale.
"""
from __future__ import annotations

import functools
import json
import math
from typing import Any

import numpy as np

from rh_common import sh
from rh_common.colourspace import luminance

from .sunsky import SUNSKY_BAKE_HEIGHT, sun_direction

__all__ = ["OLAT_HEIGHT", "OLAT_RADIUS_RANGE_DEG", "DIRECTION_SETS", "olat_directions", "check_olat_params",
           "olat_params", "olat_map", "olat_scale", "olat_world_direction", "olat_record", "solid_angle"]

OLAT_HEIGHT = SUNSKY_BAKE_HEIGHT  # 1024 x 512 like every other map: a texel is 0.35 degrees at the equator
OLAT_RADIUS_RANGE_DEG = (0.5, 20.0)  # from about one and a half texels wide to a large softbox
_SUPERSAMPLE = 8


def _rings16() -> tuple[tuple[float, float], ...]:
    # 12 above the horizon (4 high at 65 degrees between the axes, 8 at 25 degrees every 45 degrees: front 270,
    # back 90, both sides), 4 below at -25 degrees (light bounced off a floor, or a light stage's lower ring).
    return (tuple((45.0 + 90.0 * k, 65.0) for k in range(4)) + tuple((45.0 * k, 25.0) for k in range(8))
            + tuple((90.0 * k, -25.0) for k in range(4)))


def _fibonacci16() -> tuple[tuple[float, float], ...]:
    # The 16 highest of 24 spherical-Fibonacci directions: 12 above the horizon, 4 just below (down to -17 degrees).
    out = []
    for x, y, z in sh.fibonacci_sphere(24)[:16]:
        out.append((math.degrees(math.atan2(y, x)) % 360.0, math.degrees(math.asin(max(-1.0, min(1.0, z))))))
    return tuple(out)


DIRECTION_SETS: dict[str, tuple[tuple[float, float], ...]] = {"rings16": _rings16(), "fibonacci16": _fibonacci16()}
"""Named direction sets of the olat split: name -> ((azimuth_deg, elevation_deg), ...), in frame order."""


def olat_directions(name: str) -> tuple[tuple[float, float], ...]:
    """The (azimuth_deg, elevation_deg) pairs of a named direction set; ValueError (one line) for an unknown name."""
    if name not in DIRECTION_SETS:
        raise ValueError(f"unknown OLAT direction set {name!r}; known: {', '.join(DIRECTION_SETS)}")
    return DIRECTION_SETS[name]


def solid_angle(radius_deg: float) -> float:
    """Solid angle (sr) of a cone of angular radius `radius_deg`: 2π(1 − cos α)."""
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(radius_deg)))


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def check_radius(radius_deg: Any, where: str = "radius_deg") -> None:
    """One-line ValueError unless `radius_deg` gives a positive solid angle the map resolves."""
    lo, hi = OLAT_RADIUS_RANGE_DEG
    if not _is_num(radius_deg) or radius_deg <= 0:
        raise ValueError(f"{where} must be a number > 0 (the light's solid angle 2π(1 − cos r) must be positive), "
                         f"got {radius_deg!r}")
    if not lo <= radius_deg <= hi:
        raise ValueError(f"{where} must be in [{lo:g}, {hi:g}] degrees (below {lo:g} the {2 * OLAT_HEIGHT}-wide "
                         f"map cannot resolve the disc; above {hi:g} it is no longer a small light), got {radius_deg!r}")


def check_colour(colour: Any, where: str = "colour") -> None:
    if not (isinstance(colour, list) and len(colour) == 3 and all(_is_num(c) and 0 <= c <= 1 for c in colour)
            and max(colour) > 0):
        raise ValueError(f"{where} must be a list of 3 numbers in [0, 1], not all 0 (linear Rec.709), got {colour!r}")


_PARAM_KEYS = ("azimuth_deg", "elevation_deg", "radius_deg", "colour")


def check_olat_params(params: Any) -> None:
    """Raise ValueError (one line, naming the field) unless `params` describes an OLAT map (`olat_params`)."""
    if not isinstance(params, dict) or set(params) != set(_PARAM_KEYS):
        got = sorted(params) if isinstance(params, dict) else type(params).__name__
        raise ValueError(f"LightSpec.params: olat must have exactly the keys {sorted(_PARAM_KEYS)}, got {got}")
    if not (_is_num(params["azimuth_deg"]) and 0 <= params["azimuth_deg"] < 360):
        raise ValueError(f"LightSpec.params: azimuth_deg must be a number in [0, 360), got {params['azimuth_deg']!r}")
    if not (_is_num(params["elevation_deg"]) and -90 <= params["elevation_deg"] <= 90):
        raise ValueError(f"LightSpec.params: elevation_deg must be a number in [-90, 90], "
                         f"got {params['elevation_deg']!r}")
    check_radius(params["radius_deg"], "LightSpec.params: radius_deg")
    check_colour(params["colour"], "LightSpec.params: colour")


def olat_params(azimuth_deg: float, elevation_deg: float, radius_deg: float, colour=(1.0, 1.0, 1.0)) -> dict:
    """The JSON-ready params of an OLAT light (checked)."""
    p = {"azimuth_deg": float(azimuth_deg) % 360.0, "elevation_deg": float(elevation_deg),
         "radius_deg": float(radius_deg), "colour": [float(c) for c in colour]}
    check_olat_params(p)
    return p


def _coverage(H: int, d: np.ndarray, alpha: float) -> np.ndarray:
    """(H, 2H) fraction of each texel's solid angle inside the cone (axis d, half-angle alpha), by 8x8 sub-cells."""
    W, s = 2 * H, _SUPERSAMPLE
    theta_c = math.acos(max(-1.0, min(1.0, float(d[2]))))
    pad = 2.0 * math.pi / H  # two rows of margin
    j0 = max(0, int(math.floor((theta_c - alpha - pad) / math.pi * H)))
    j1 = min(H, int(math.ceil((theta_c + alpha + pad) / math.pi * H)))
    edges = (j0 + np.arange((j1 - j0) * s + 1) / s) * (math.pi / H)  # sub-row edges in θ
    t_mid = 0.5 * (edges[:-1] + edges[1:])
    w_row = (2.0 * math.pi / (W * s)) * (np.cos(edges[:-1]) - np.cos(edges[1:]))  # exact sub-cell solid angles
    phi = math.pi - (np.arange(W * s) + 0.5) * (2.0 * math.pi / (W * s))  # sub-column centres, as sh's mapping
    st = np.sin(t_mid)[:, None]
    cos_angle = st * (np.cos(phi)[None, :] * d[0] + np.sin(phi)[None, :] * d[1]) + np.cos(t_mid)[:, None] * d[2]
    inside = (cos_angle >= math.cos(alpha)) * w_row[:, None]
    cov = np.zeros((H, W))
    cov[j0:j1] = inside.reshape(j1 - j0, s, W, s).sum(axis=(1, 3)) / sh.pixel_solid_angles(H, W)[j0:j1]
    return cov


@functools.lru_cache(maxsize=8)
def _map_cached(key: str, height: int) -> np.ndarray:
    p = json.loads(key)
    alpha = math.radians(p["radius_deg"])
    cov = _coverage(height, sun_direction(p["azimuth_deg"], p["elevation_deg"]), alpha)
    omega = sh.pixel_solid_angles(height, 2 * height)
    cov *= solid_angle(p["radius_deg"]) / float(np.sum(cov * omega))  # the cone's solid angle exactly
    out = np.ascontiguousarray(cov[..., None] * np.asarray(p["colour"], dtype=np.float64), dtype=np.float32)
    out.setflags(write=False)
    return out


def olat_map(params: dict, height: int = OLAT_HEIGHT) -> np.ndarray:
    """The (height, 2·height, 3) float32 map of unit radiance times `colour` in the disc, read-only (cached)."""
    check_olat_params(params)
    return _map_cached(json.dumps(params, sort_keys=True), int(height))


def _facing_irradiance(radiance: np.ndarray, d: np.ndarray) -> np.ndarray:
    from .light import brute_force_irradiance  # light.py builds OLAT maps from this module: import when called

    return brute_force_irradiance(radiance, np.asarray(d, dtype=np.float64)[None])[0]


def olat_scale(params: dict) -> float:
    """The LightSpec `scale` that gives a surface facing the light irradiance of luminance π (module docstring)."""
    d = sun_direction(params["azimuth_deg"], params["elevation_deg"])
    return float(math.pi / float(luminance(_facing_irradiance(olat_map(params), d))))


def olat_world_direction(params: dict, rotation_deg: float) -> np.ndarray:
    """Unit world direction towards the light: the params' direction turned by the LightSpec's rotation about +Z."""
    from .mitsuba_env import rotation_z

    return rotation_z(rotation_deg) @ sun_direction(params["azimuth_deg"], params["elevation_deg"])


def olat_record(light, direction_set: str, direction_index: int) -> dict:
    """The frame JSON's `light.olat` block of a built OLAT light (`Light` of kind 'olat'): its place in the set,
    world direction, solid angle (sr), radiance (RGB, scale included) and the irradiance E_facing it gives a surface
    facing it, both of the map that was rendered (`irradiance_facing`) and of the ideal cone (π sin²α L)."""
    p = light.spec.params
    d = olat_world_direction(p, light.spec.rotation_deg)
    radiance = light.spec.scale * np.asarray(p["colour"], dtype=np.float64)
    e_map = _facing_irradiance(light.radiance, sun_direction(p["azimuth_deg"], p["elevation_deg"]))
    cone = math.pi * math.sin(math.radians(p["radius_deg"])) ** 2 * radiance
    return {"direction_set": direction_set, "direction_index": int(direction_index),
            "direction_world": [float(x) for x in d], "solid_angle_sr": solid_angle(p["radius_deg"]),
            "radiance": [float(x) for x in radiance], "irradiance_facing": [float(x) for x in e_map],
            "irradiance_facing_cone": [float(x) for x in cone]}
