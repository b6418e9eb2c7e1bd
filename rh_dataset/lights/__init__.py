"""Lights: HDRI library, sunsky bake, exposure normalisation, SH of the light, the Mitsuba emitter.

Conventions: docs/ARCHITECTURE.md ("Environment lights", "Spherical harmonics"); SH maths in `rh_common.sh`.
`Light.radiance` is scaled but NOT rotated; the rotation lives in the Mitsuba `to_world` and in `sh_world`
(see `rh_dataset.lights.light`).
"""
from __future__ import annotations

from .library import (
    DEBIAN_STUDIOLIGHTS,
    HdriError,
    bundled_hdris,
    downsample_equirect,
    hdri_library,
    load_hdri,
    normalised_scale,
)
from .light import (
    SUNSKY_ELEVATION_RANGE_DEG,
    SUNSKY_TURBIDITY_RANGE,
    Light,
    LightSpec,
    TruncationError,
    brute_force_irradiance,
    build_light,
    mitsuba_emitter_dict,
    rotate_equirect,
    sample_light,
    sh_truncation_error,
)
from .mitsuba_env import ENVMAP_BASIS, envmap_to_world, mitsuba_envmap_array, mitsuba_envmap_data, rotation_z
from .sunsky import SUN_APERTURE_DEG, bake_sunsky, sun_direction

__all__ = [
    "DEBIAN_STUDIOLIGHTS",
    "ENVMAP_BASIS",
    "HdriError",
    "Light",
    "LightSpec",
    "SUN_APERTURE_DEG",
    "SUNSKY_ELEVATION_RANGE_DEG",
    "SUNSKY_TURBIDITY_RANGE",
    "TruncationError",
    "bake_sunsky",
    "brute_force_irradiance",
    "build_light",
    "bundled_hdris",
    "downsample_equirect",
    "envmap_to_world",
    "hdri_library",
    "load_hdri",
    "mitsuba_emitter_dict",
    "mitsuba_envmap_array",
    "mitsuba_envmap_data",
    "normalised_scale",
    "rotate_equirect",
    "rotation_z",
    "sample_light",
    "sh_truncation_error",
    "sun_direction",
]
