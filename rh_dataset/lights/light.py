"""Light specs, sampling, building (map + SH) and the Mitsuba emitter.

Rotation design: `Light.radiance` is the scaled map in the **light's own frame (not rotated)**. The rotation about
+Z is applied exactly and without resampling in both places that use the light:
* rendering: Mitsuba's envmap `to_world` = ``Rz(rotation_deg) @ ENVMAP_BASIS`` (see `mitsuba_env`);
* SH: ``sh_world = sh.rotate(sh.project_equirect(radiance), Rz(rotation_deg))``.
Resampling the map instead would blur a one-pixel sun unless the angle were a multiple of 360°/W.
`Light.world_radiance()` gives the rotated map in the world frame when an image is needed (exact column roll for
multiples of the pixel width, otherwise the same linear interpolation in u that Mitsuba performs).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Literal, Mapping

import numpy as np

from rh_common import sh
from rh_common.colourspace import luminance

from ..variant import ensure_variant
from .library import load_hdri
from .mitsuba_env import envmap_to_world, mitsuba_envmap_array, rotation_z
from .olat import check_olat_params, olat_map
from .procedural import PROCEDURAL_KINDS, check_params, procedural_map
from .sunsky import bake_sunsky

__all__ = [
    "LIGHT_KINDS",
    "LightSpec",
    "Light",
    "SUNSKY_ELEVATION_RANGE_DEG",
    "SUNSKY_TURBIDITY_RANGE",
    "build_light",
    "mitsuba_emitter_dict",
    "rotate_equirect",
    "brute_force_irradiance",
    "TruncationError",
    "K2_MAX_ERROR",
    "sh_truncation_error",
]

# Sampled daylight: sun high enough to light a standing person from above the horizon haze, not so high that
# every frame is noon; turbidity from arctic-clear (2) to warm/moist (6), inside the model's 1–10 range.
SUNSKY_ELEVATION_RANGE_DEG = (10.0, 70.0)
SUNSKY_TURBIDITY_RANGE = (2.0, 6.0)


def _is_real(x: object) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) and math.isfinite(x)


LIGHT_KINDS = ("envmap", "sunsky", *PROCEDURAL_KINDS, "olat")


@dataclass(frozen=True)
class LightSpec:
    """What light a frame uses; reproduces the light exactly (with the file at `source`).

    kind: 'envmap' (an HDRI file), 'sunsky' (Mitsuba's sunsky, baked) or a procedural kind ('studio', 'window',
    'outdoor'; `rh_dataset.lights.procedural`). name: library name / the kind. source: the HDRI path for
    'envmap', '' otherwise. rotation_deg: about +Z, counter-clockwise from above. scale: multiplier applied to the
    map (includes the exposure normalisation). sun_*: degrees, azimuth counter-clockwise from +X, elevation above
    the horizon in [0, 90]; turbidity in [1, 10]; only for 'sunsky'. params: the procedural map's JSON-ready
    description (`procedural.check_params`), only for procedural kinds, or the disc of an 'olat' light (one small
    light at infinity, `olat.check_olat_params`); `as_dict` leaves it out when None, so the frame JSON of an envmap
    or sunsky light is what it was before procedural kinds existed.
    """

    kind: Literal["envmap", "sunsky", "studio", "window", "outdoor", "olat"]
    name: str
    source: str
    rotation_deg: float
    scale: float
    sun_azimuth_deg: float | None = None
    sun_elevation_deg: float | None = None
    turbidity: float | None = None
    params: dict | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        if self.kind not in LIGHT_KINDS:
            raise ValueError(f"LightSpec.kind must be one of {', '.join(LIGHT_KINDS)}, got {self.kind!r}")
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"LightSpec.name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.source, str):
            raise ValueError(f"LightSpec.source must be a string, got {self.source!r}")
        if not _is_real(self.rotation_deg):
            raise ValueError(f"LightSpec.rotation_deg must be a finite number, got {self.rotation_deg!r}")
        if not (_is_real(self.scale) and self.scale > 0):
            raise ValueError(f"LightSpec.scale must be a finite number > 0, got {self.scale!r}")
        sun = {"sun_azimuth_deg": self.sun_azimuth_deg, "sun_elevation_deg": self.sun_elevation_deg,
               "turbidity": self.turbidity}
        if self.kind != "sunsky":
            for name, value in sun.items():
                if value is not None:
                    raise ValueError(f"LightSpec.{name} must be None for kind {self.kind!r}, got {value!r}")
        if self.kind in PROCEDURAL_KINDS or self.kind == "olat":
            if self.source != "":
                raise ValueError(f"LightSpec.source must be '' for kind {self.kind!r}, got {self.source!r}")
            if self.kind == "olat":
                check_olat_params(self.params)
            else:
                check_params(self.kind, self.params)
            return
        if self.params is not None:
            raise ValueError(f"LightSpec.params must be None for kind {self.kind!r}, got {self.params!r}")
        if self.kind == "envmap":
            if not self.source:
                raise ValueError("LightSpec.source must be the HDRI file path for kind 'envmap', got ''")
            return
        if self.source != "":
            raise ValueError(f"LightSpec.source must be '' for kind 'sunsky', got {self.source!r}")
        for name, value in sun.items():
            if not _is_real(value):
                raise ValueError(f"LightSpec.{name} must be a finite number for kind 'sunsky', got {value!r}")
        if not 0.0 <= self.sun_elevation_deg <= 90.0:  # type: ignore[operator]
            raise ValueError(f"LightSpec.sun_elevation_deg must be in [0, 90], got {self.sun_elevation_deg!r}")
        if not 1.0 <= self.turbidity <= 10.0:  # type: ignore[operator]
            raise ValueError(f"LightSpec.turbidity must be in [1, 10] (sky model range), got {self.turbidity!r}")

    def as_dict(self) -> dict:
        """Plain JSON-ready dict of the fields (frame JSON `light` block, minus the SH and clamp count);
        `params` only for procedural kinds."""
        d = dataclasses.asdict(self)
        if d["params"] is None:
            del d["params"]
        return d

    @classmethod
    def from_json(cls, light: Mapping, where: str, source: str | None = None) -> "LightSpec":
        """The spec of a frame JSON's `light` block (`as_dict` plus the SH), `source` replacing the recorded
        (base-name) one when given. Raises ValueError naming `where` (the frame JSON) for an unknown kind or a
        bad field."""
        keys = ("kind", "name", "source", "rotation_deg", "scale", "sun_azimuth_deg", "sun_elevation_deg",
                "turbidity", "params")
        try:
            fields = {k: light.get(k) for k in keys}
            if source is not None:
                fields["source"] = source
            return cls(**fields)
        except (ValueError, TypeError, AttributeError) as exc:
            raise ValueError(f"{where}: light: {exc}; regenerate the frame with this version of rh-generate") \
                from None


@dataclass(frozen=True, eq=False)  # eq=False: arrays make field-wise == ambiguous; identity semantics instead
class Light:
    """A built light.

    radiance: (H, W, 3) float32, read-only: the map **after `scale`, before rotation** (light frame; ARCHITECTURE.md
      mapping). This is exactly the data Mitsuba gets (`mitsuba_emitter_dict`), rotation going into `to_world`.
    sh_world: (9, 3) float64, read-only: SH of the scaled **and rotated** map in the world frame
      (= sh.rotate(sh.project_equirect(radiance), Rz(rotation_deg))), i.e. of what Mitsuba renders.
    negative_pixels_clamped: channel values < 0 set to 0 on load.
    """

    spec: LightSpec
    radiance: np.ndarray
    sh_world: np.ndarray
    negative_pixels_clamped: int

    @property
    def rotation(self) -> np.ndarray:
        """3x3 rotation about +Z by spec.rotation_deg (light frame → world frame)."""
        return rotation_z(self.spec.rotation_deg)

    @property
    def to_world(self) -> np.ndarray:
        """4x4 Mitsuba envmap `to_world` (our mapping, rotated)."""
        return envmap_to_world(self.spec.rotation_deg)

    def world_radiance(self) -> np.ndarray:
        """The scaled map rotated into the world frame, (H, W, 3) float32 (see `rotate_equirect`)."""
        return rotate_equirect(self.radiance, self.spec.rotation_deg)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def _base_map(spec: LightSpec) -> tuple[np.ndarray, int]:
    if spec.kind == "envmap":
        return load_hdri(spec.source)
    if spec.kind in PROCEDURAL_KINDS:
        return procedural_map(spec.kind, spec.params), 0  # type: ignore[arg-type]
    if spec.kind == "olat":
        return olat_map(spec.params), 0  # type: ignore[arg-type]
    return bake_sunsky(spec.sun_azimuth_deg, spec.sun_elevation_deg, spec.turbidity), 0  # type: ignore[arg-type]


def build_light(spec: LightSpec) -> Light:
    """Load (or bake) the map, apply `scale`, and compute `sh_world` of the rotated map. See `Light`."""
    base, clamped = _base_map(spec)
    radiance = _readonly((base * np.float32(spec.scale)).astype(np.float32))
    # Project the float32 values Mitsuba will receive, then rotate the coefficients (exact, no resampling).
    coeffs = sh.rotate(sh.project_equirect(radiance), rotation_z(spec.rotation_deg))
    return Light(spec=spec, radiance=radiance, sh_world=_readonly(coeffs), negative_pixels_clamped=clamped)


def mitsuba_emitter_dict(light: Light) -> dict:
    """Mitsuba `envmap` dict rendering exactly `light` in our +Z-up world.

    ``{'type': 'envmap', 'bitmap': mi.Bitmap((2H+1, W, 3) float32), 'to_world': Rz(rotation) @ ENVMAP_BASIS,
    'scale': 1.0}``; `scale` is already in the bitmap. The bitmap has 2H+1 rows (see `mitsuba_env`): Mitsuba
    places bitmap rows at the poles, this layout makes its lookup return our pixel values at our pixel centres.
    Needs a Mitsuba variant; if none is set, sets `llvm_ad_rgb` (the project's default), never switches one.
    """
    mi = ensure_variant()
    return {
        "type": "envmap",
        "bitmap": mi.Bitmap(mitsuba_envmap_array(light.radiance)),
        "to_world": mi.ScalarTransform4f(light.to_world.tolist()),
        "scale": 1.0,
    }


def rotate_equirect(radiance: np.ndarray, rotation_deg: float) -> np.ndarray:
    """Rotate an equirect map about +Z (counter-clockwise from above): ``L'(ω) = L(Rz(−α) ω)``, float32.

    Rotation only shifts columns: new column i takes the old value at ``u = i + 0.5 + α/360·W``. A whole number of
    pixels is an exact roll; otherwise linear interpolation in u, periodic (what Mitsuba's lookup does in u).
    """
    L = np.asarray(radiance, dtype=np.float32)
    W = L.shape[1]
    shift = (rotation_deg / 360.0) * W
    whole = round(shift)
    if abs(shift - whole) < 1e-9:
        return np.roll(L, -int(whole), axis=1)
    pos = np.arange(W) + shift
    i0 = np.floor(pos).astype(np.int64)
    f = (pos - i0).astype(np.float32)[None, :, None]
    return ((1.0 - f) * L[:, i0 % W] + f * L[:, (i0 + 1) % W]).astype(np.float32)


def brute_force_irradiance(radiance: np.ndarray, normals: np.ndarray, chunk: int = 16) -> np.ndarray:
    """Reference irradiance (N, 3) float64: ``E(n) = Σ_pixels L · max(0, n·ω) · Ω`` at pixel centres."""
    L = np.asarray(radiance, dtype=np.float64)
    H, W, C = L.shape
    dirs = sh.equirect_directions(H, W).reshape(-1, 3)
    weighted = (L * sh.pixel_solid_angles(H, W)[..., None]).reshape(-1, C)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = np.empty((n.shape[0], C))
    for s in range(0, n.shape[0], chunk):  # chunked: N x (H·W) cosines would not fit in memory at full size
        cos = np.maximum(n[s:s + chunk] @ dirs.T, 0.0)
        out[s:s + chunk] = cos @ weighted
    return out


@dataclass(frozen=True, eq=False)
class TruncationError:
    """Order-2 SH irradiance vs brute force, per normal (luminance).

    relative: |E_sh − E| / E(n); relative_to_mean: |E_sh − E| / mean_n E(n);
    bound: the rigorous per-normal bound on `relative`, (3/32) ∫L dω / E(n). It holds because the order-2
    truncation K₂(t) = 1/4 + t/2 + (5/32)(3t² − 1) of the clamped cosine K(t) = max(0, t) satisfies
    |K − K₂| ≤ 3/32 for t in [−1, 1] (maximum at grazing t = 0) and L ≥ 0.
    """

    relative: np.ndarray
    relative_to_mean: np.ndarray
    bound: np.ndarray

    @property
    def mean(self) -> float:
        return float(np.mean(self.relative))

    @property
    def p95(self) -> float:
        return float(np.percentile(self.relative, 95))

    @property
    def max(self) -> float:
        return float(np.max(self.relative))


K2_MAX_ERROR = 3.0 / 32.0


def sh_truncation_error(radiance: np.ndarray, normals: np.ndarray) -> TruncationError:
    """Compare sh.irradiance(sh.project_equirect(radiance), n) with `brute_force_irradiance` at `normals`.

    Normals with zero reference irradiance (e.g. straight down under a sky) get relative error measured against
    1e-6 of the mean irradiance rather than dividing by zero.
    """
    L = np.asarray(radiance, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    e_ref = luminance(brute_force_irradiance(L, n)).astype(np.float64)
    e_sh = luminance(sh.irradiance(sh.project_equirect(L), n)).astype(np.float64)
    H, W, _ = L.shape
    power = float(np.sum(luminance(L).astype(np.float64) * sh.pixel_solid_angles(H, W)))
    mean_e = float(np.mean(e_ref))
    denom = np.maximum(e_ref, 1e-6 * mean_e)
    err = np.abs(e_sh - e_ref)
    return TruncationError(relative=err / denom, relative_to_mean=err / mean_e,
                           bound=K2_MAX_ERROR * power / denom)
