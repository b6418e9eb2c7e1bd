"""Lights: HDRI library, sunsky bake, procedural maps, one-light-at-a-time (OLAT) discs, sampling (mixtures),
exposure normalisation, SH of the light, the Mitsuba emitter.

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
    LIGHT_KINDS,
    rotate_equirect,
    sh_truncation_error,
)
from .olat import DIRECTION_SETS, olat_directions, olat_map, olat_params, olat_record, olat_scale
from .procedural import PROCEDURAL_KINDS, check_params, procedural_map, sample_params
from .sampling import MIXTURE_KEYS, check_mixture, sample_light
from .mitsuba_env import ENVMAP_BASIS, envmap_to_world, mitsuba_envmap_array, mitsuba_envmap_data, rotation_z
from .sunsky import SUN_APERTURE_DEG, bake_sunsky, sun_direction

__all__ = [
    "DEBIAN_STUDIOLIGHTS",
    "DIRECTION_SETS",
    "ENVMAP_BASIS",
    "HdriError",
    "LIGHT_KINDS",
    "MIXTURE_KEYS",
    "PROCEDURAL_KINDS",
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
    "check_mixture",
    "check_params",
    "downsample_equirect",
    "envmap_to_world",
    "hdri_library",
    "load_hdri",
    "mitsuba_emitter_dict",
    "mitsuba_envmap_array",
    "mitsuba_envmap_data",
    "normalised_scale",
    "olat_directions",
    "olat_map",
    "olat_params",
    "olat_record",
    "olat_scale",
    "procedural_map",
    "rotate_equirect",
    "rotation_z",
    "sample_light",
    "sample_params",
    "sh_truncation_error",
    "sun_direction",
]
