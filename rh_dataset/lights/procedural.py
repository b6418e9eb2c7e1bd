"""Procedural environment maps: a seeded parameter dict in, an equirectangular float32 map out.

Three kinds (docs/ARCHITECTURE.md, "Procedural environments"):
* ``studio``: a dim room and 1-4 rectangular area lights (softboxes, strip lights) in the roles key, fill, rim
  and top, each with a size, a black-body colour temperature, an optional coloured gel and an intensity ratio;
* ``window``: a dim room lit by one or two bright openings (daylight sky above the sill line, ground below,
  optional mullions);
* ``outdoor``: Mitsuba's `sunsky` baked to a map (`sunsky.bake_sunsky`) plus a diffuse ground that reflects the
  sky's own horizontal irradiance (Mitsuba's sunsky is black below the horizon).

`sample_params(kind, rng)` draws a JSON-ready dict (plain floats, ints, lists); `procedural_map(kind, params)` is a
pure function of it, so the dict in a frame JSON rebuilds the map bit for bit. Maps use the directions of
ARCHITECTURE.md (+Z up, `sh.equirect_directions`), are non-negative and finite, in arbitrary units (the sampler
normalises them as it does any map). Rectangles are angular: a light centred on direction c with right axis r
(horizontal) and up axis u covers the directions whose angles atan2(d·r, d·c) and atan2(d·u, d·c) lie within
half its width and height, with an edge feathered over a few percent of its size (softboxes are not hard-edged).
"""
from __future__ import annotations

import colorsys
import functools
import json
import math
from typing import Any

import numpy as np

from rh_common import sh
from rh_common.colourspace import cct_to_linear_srgb

from .sunsky import SUNSKY_BAKE_HEIGHT, bake_sunsky, sun_direction

__all__ = ["PROCEDURAL_KINDS", "PROCEDURAL_HEIGHT", "OUTDOOR_ELEVATION_RANGE_DEG", "OUTDOOR_TURBIDITY_RANGE",
           "sample_params", "check_params", "procedural_map"]

PROCEDURAL_KINDS = ("studio", "window", "outdoor")
PROCEDURAL_HEIGHT = SUNSKY_BAKE_HEIGHT  # 1024 x 512, the bundled maps' size
STUDIO_ROLES = ("key", "fill", "rim", "top")
# Outdoor daylight: from a low sun (long shadows, warm light) to a high one; clear to hazy skies (model: 1-10).
OUTDOOR_ELEVATION_RANGE_DEG = (5.0, 75.0)
OUTDOOR_TURBIDITY_RANGE = (2.0, 8.0)
_FEATHER = 0.06  # edge softness, a fraction of the light's half size


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _gel(rng: np.random.Generator) -> list[float]:
    # A coloured filter: a saturated hue's transmittance (brightest channel 1).
    r, g, b = colorsys.hsv_to_rgb(_u(rng, 0.0, 1.0), _u(rng, 0.4, 0.9), 1.0)
    return [float(r), float(g), float(b)]


def _studio_light(rng: np.random.Generator, role: str, key_az: float, cct: float) -> dict:
    # Draw order per light is fixed: placement, shape and size, colour, gel, intensity.
    if role == "key":
        az, el = key_az, _u(rng, 15.0, 50.0)
    elif role == "fill":
        az, el = key_az + float(rng.choice([-1.0, 1.0])) * _u(rng, 60.0, 120.0), _u(rng, 0.0, 30.0)
    elif role == "rim":
        az, el = key_az + 180.0 + _u(rng, -60.0, 60.0), _u(rng, 10.0, 45.0)
    else:  # top
        az, el = _u(rng, 0.0, 360.0), _u(rng, 60.0, 85.0)
    strip = rng.random() < (0.8 if role == "rim" else 0.3)
    if strip:
        width, height = _u(rng, 4.0, 10.0), _u(rng, 30.0, 70.0)
    else:
        width, height = _u(rng, 12.0, 40.0), _u(rng, 12.0, 45.0)
    cct_light = cct if rng.random() < 0.5 else _u(rng, 2700.0, 7500.0)
    gel = _gel(rng) if rng.random() < 0.25 else [1.0, 1.0, 1.0]
    intensity = {"key": 1.0, "fill": _u(rng, 0.1, 0.5), "rim": _u(rng, 0.5, 2.0), "top": _u(rng, 0.2, 0.8)}[role]
    return {"role": role, "shape": "strip" if strip else "softbox", "azimuth_deg": az % 360.0, "elevation_deg": el,
            "width_deg": width, "height_deg": height, "cct_k": cct_light, "gel": gel, "intensity": intensity}


def _sample_studio(rng: np.random.Generator) -> dict:
    n = int(rng.integers(1, 5))
    others = sorted(int(k) for k in rng.choice(3, size=n - 1, replace=False)) if n > 1 else []
    roles = ["key"] + [STUDIO_ROLES[1 + k] for k in others]
    key_az, cct = _u(rng, 0.0, 360.0), _u(rng, 2800.0, 6500.0)
    lights = [_studio_light(rng, role, key_az, cct) for role in roles]
    return {"room_level": _u(rng, 0.002, 0.02), "room_cct_k": _u(rng, 3000.0, 6500.0),
            "floor_factor": _u(rng, 0.5, 1.5), "lights": lights}


def _sample_window(rng: np.random.Generator) -> dict:
    n = int(rng.integers(1, 3))
    first = _u(rng, 0.0, 360.0)
    openings = []
    for k in range(n):
        az = first if k == 0 else first + _u(rng, 60.0, 300.0)
        openings.append({"azimuth_deg": az % 360.0, "elevation_deg": _u(rng, 5.0, 30.0),
                         "width_deg": _u(rng, 15.0, 60.0), "height_deg": _u(rng, 25.0, 70.0),
                         "sky_cct_k": _u(rng, 5500.0, 12000.0), "intensity": 1.0 if k == 0 else _u(rng, 0.3, 1.0),
                         "ground_factor": _u(rng, 0.1, 0.4), "mullions": int(rng.integers(0, 2))})
    return {"room_level": _u(rng, 0.005, 0.04), "room_cct_k": _u(rng, 3000.0, 6500.0),
            "floor_factor": _u(rng, 0.5, 1.5), "openings": openings}


def _sample_outdoor(rng: np.random.Generator) -> dict:
    az = _u(rng, 0.0, 360.0)
    el = _u(rng, *OUTDOOR_ELEVATION_RANGE_DEG)
    turb = _u(rng, *OUTDOOR_TURBIDITY_RANGE)
    grey = _u(rng, 0.08, 0.3)
    tint = rng.uniform(0.75, 1.25, size=3)
    albedo = [float(min(0.95, grey * t)) for t in tint]
    return {"sun_azimuth_deg": az, "sun_elevation_deg": el, "turbidity": turb, "ground_albedo": albedo}


_SAMPLERS = {"studio": _sample_studio, "window": _sample_window, "outdoor": _sample_outdoor}


def sample_params(kind: str, rng: np.random.Generator) -> dict:
    """Draw the JSON-ready parameters of a `kind` map from `rng` (a fixed draw order: a seed reproduces them)."""
    if kind not in _SAMPLERS:
        raise ValueError(f"unknown procedural light kind {kind!r}; known: {', '.join(PROCEDURAL_KINDS)}")
    return _SAMPLERS[kind](rng)


# ---------------------------------------------------------------------------------------------- checking
def _num(where: str, v: Any, lo: float, hi: float) -> None:
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and lo <= v <= hi
    if not ok:
        raise ValueError(f"LightSpec.params: {where} must be a number in [{lo:g}, {hi:g}], got {v!r}")


def _rgb(where: str, v: Any, hi: float = 1.0) -> None:
    if not (isinstance(v, list) and len(v) == 3):
        raise ValueError(f"LightSpec.params: {where} must be a list of 3 numbers, got {v!r}")
    for c in v:
        _num(where, c, 0.0, hi)


def _keys(where: str, d: Any, keys: set[str]) -> None:
    if not isinstance(d, dict) or set(d) != keys:
        got = sorted(d) if isinstance(d, dict) else type(d).__name__
        raise ValueError(f"LightSpec.params: {where} must have exactly the keys {sorted(keys)}, got {got}")


def _check_rect(where: str, r: dict) -> None:
    _num(f"{where}.azimuth_deg", r["azimuth_deg"], 0.0, 360.0)
    _num(f"{where}.elevation_deg", r["elevation_deg"], -89.0, 89.0)
    _num(f"{where}.width_deg", r["width_deg"], 0.5, 170.0)
    _num(f"{where}.height_deg", r["height_deg"], 0.5, 170.0)
    _num(f"{where}.intensity", r["intensity"], 0.0, 1e6)


def _check_room(p: dict) -> None:
    _num("room_level", p["room_level"], 0.0, 1e6)
    _num("room_cct_k", p["room_cct_k"], 1667.0, 25000.0)
    _num("floor_factor", p["floor_factor"], 0.0, 1e3)


_RECT_KEYS = {"azimuth_deg", "elevation_deg", "width_deg", "height_deg", "intensity"}


def _room_and_rects(params: Any, field: str, most: int, extra: set[str]) -> list[tuple[str, dict]]:
    """Check a room-with-rectangles description (keys, room, each rectangle); (name, rectangle) pairs."""
    _keys(field, params, {"room_level", "room_cct_k", "floor_factor", field})
    _check_room(params)
    rects = params[field]
    if not (isinstance(rects, list) and 1 <= len(rects) <= most):
        raise ValueError(f"LightSpec.params: {field} must be a list of 1-{most} entries, got {rects!r}")
    named = [(f"{field}[{k}]", r) for k, r in enumerate(rects)]
    for w, r in named:
        _keys(w, r, _RECT_KEYS | extra)
        _check_rect(w, r)
    return named


def check_params(kind: str, params: Any) -> None:
    """Raise ValueError (one line, naming the field) unless `params` is a valid description of a `kind` map."""
    if kind == "studio":
        for w, lt in _room_and_rects(params, "lights", 8, {"role", "shape", "cct_k", "gel"}):
            if lt["role"] not in STUDIO_ROLES or lt["shape"] not in ("softbox", "strip"):
                raise ValueError(f"LightSpec.params: {w} role must be one of {STUDIO_ROLES} and shape 'softbox' or "
                                 f"'strip', got {lt['role']!r}, {lt['shape']!r}")
            _num(f"{w}.cct_k", lt["cct_k"], 1667.0, 25000.0)
            _rgb(f"{w}.gel", lt["gel"])
    elif kind == "window":
        for w, op in _room_and_rects(params, "openings", 4, {"sky_cct_k", "ground_factor", "mullions"}):
            _num(f"{w}.sky_cct_k", op["sky_cct_k"], 1667.0, 25000.0)
            _num(f"{w}.ground_factor", op["ground_factor"], 0.0, 10.0)
            if op["mullions"] not in (0, 1) or isinstance(op["mullions"], bool):
                raise ValueError(f"LightSpec.params: {w}.mullions must be 0 or 1, got {op['mullions']!r}")
    elif kind == "outdoor":
        _keys("outdoor", params, {"sun_azimuth_deg", "sun_elevation_deg", "turbidity", "ground_albedo"})
        _num("sun_azimuth_deg", params["sun_azimuth_deg"], 0.0, 360.0)
        _num("sun_elevation_deg", params["sun_elevation_deg"], 0.0, 90.0)
        _num("turbidity", params["turbidity"], 1.0, 10.0)
        _rgb("ground_albedo", params["ground_albedo"])
    else:
        raise ValueError(f"unknown procedural light kind {kind!r}; known: {', '.join(PROCEDURAL_KINDS)}")


# ---------------------------------------------------------------------------------------------- drawing
def _rect_mask(dirs: np.ndarray, r: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """(H, W) coverage in [0, 1] of the angular rectangle `r` (see the module docstring), its two angles |a|, |b|
    per pixel and its half width and height (radians)."""
    c = sun_direction(r["azimuth_deg"], r["elevation_deg"])
    right = np.cross(c, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)  # |elevation| <= 89°: never parallel to +Z
    up = np.cross(right, c)
    p = dirs @ c
    a = np.abs(np.arctan2(dirs @ right, p))
    b = np.abs(np.arctan2(dirs @ up, p))
    hw, hh = math.radians(r["width_deg"]) / 2.0, math.radians(r["height_deg"]) / 2.0
    fw, fh = _FEATHER * hw, _FEATHER * hh
    mask = np.clip((hw - a) / fw + 0.5, 0.0, 1.0) * np.clip((hh - b) / fh + 0.5, 0.0, 1.0)
    return np.where(p > 0.0, mask, 0.0), a, b, hw, hh


def _room(dirs: np.ndarray, p: dict) -> np.ndarray:
    colour = cct_to_linear_srgb(p["room_cct_k"]) * p["room_level"]
    floor = np.where(dirs[..., 2:3] < 0.0, p["floor_factor"], 1.0)
    return floor * colour


def _studio(dirs: np.ndarray, p: dict) -> np.ndarray:
    out = _room(dirs, p)
    for lt in p["lights"]:
        mask = _rect_mask(dirs, lt)[0]
        colour = cct_to_linear_srgb(lt["cct_k"]) * np.asarray(lt["gel"], dtype=np.float64) * lt["intensity"]
        out = out + mask[..., None] * colour
    return out


def _window(dirs: np.ndarray, p: dict) -> np.ndarray:
    out = _room(dirs, p)
    for op in p["openings"]:
        mask, a, b, hw, hh = _rect_mask(dirs, op)
        if op["mullions"]:  # a cross of frame bars, 4% of the opening wide, dividing it into four panes
            bar = (a < 0.04 * hw) | (b < 0.04 * hh)
            mask = np.where(bar, 0.0, mask)
        sky = cct_to_linear_srgb(op["sky_cct_k"]) * op["intensity"]
        view = np.where(dirs[..., 2:3] < 0.0, op["ground_factor"], 1.0) * sky  # outside: ground below the horizon
        out = np.where(mask[..., None] > 0.0, (1.0 - mask[..., None]) * out + mask[..., None] * view, out)
    return out


def _outdoor(H: int, p: dict) -> np.ndarray:
    sky = np.array(bake_sunsky(p["sun_azimuth_deg"], p["sun_elevation_deg"], p["turbidity"], height=H),
                   dtype=np.float64)
    dirs = sh.equirect_directions(H, 2 * H)
    below = dirs[..., 2] < 0.0
    # A Lambertian ground lit by the baked sky and sun: radiance ρ E_h / π, E_h = ∫_{z>0} L z dω of this very map.
    cos = np.where(below, 0.0, dirs[..., 2])
    e_h = np.einsum("hwc,hw->c", sky, cos * sh.pixel_solid_angles(H, 2 * H))
    sky[below] = np.asarray(p["ground_albedo"], dtype=np.float64) * e_h / math.pi
    return sky


@functools.lru_cache(maxsize=8)
def _map_cached(kind: str, key: str, height: int) -> np.ndarray:
    params = json.loads(key)
    if kind == "outdoor":
        m = _outdoor(height, params)
    else:
        dirs = sh.equirect_directions(height, 2 * height)
        m = _studio(dirs, params) if kind == "studio" else _window(dirs, params)
    if not np.all(np.isfinite(m)):
        raise ValueError(f"procedural {kind} map has NaN/Inf for params {key}")
    out = np.ascontiguousarray(np.maximum(m, 0.0), dtype=np.float32)
    out.setflags(write=False)
    return out


def procedural_map(kind: str, params: dict, height: int = PROCEDURAL_HEIGHT) -> np.ndarray:
    """The (height, 2·height, 3) float32 map, read-only (cached: a pure function of kind, params and height)."""
    check_params(kind, params)
    return _map_cached(kind, json.dumps(params, sort_keys=True), int(height))
