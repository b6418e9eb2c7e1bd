"""A convex diffuse sphere under each bundled HDRI (and each procedural kind, and OLAT lights) renders albedo * E / pi, E the
brute-force cosine convolution.

This ties together the renderer, the environment mapping (Mitsuba's envmap vs our equirect convention), light
scale and rotation, and the normal layer: a mistake in any of them moves the rendered radiance off the integral.
"""
from __future__ import annotations

import numpy as np
import pytest

from analytic_scenes import uv_sphere
from rh_common.colourspace import luminance
from rh_dataset.lights import (PROCEDURAL_KINDS, LightSpec, brute_force_irradiance, build_light, bundled_hdris,
                               downsample_equirect, load_hdri, mitsuba_emitter_dict, normalised_scale, olat_params,
                               olat_scale, procedural_map, sample_params)
from rh_common.camera import Camera
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant

ALBEDO = np.array([0.6, 0.5, 0.4])


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


@pytest.mark.parametrize("name", sorted(bundled_hdris()))
def test_diffuse_sphere_under_hdri_matches_cosine_convolution(name):
    path = bundled_hdris()[name]
    base, _ = load_hdri(path)
    # 90 degrees is a whole number of columns of a 1024-wide map, so the brute-force map rotates exactly.
    _check_diffuse_sphere(build_light(LightSpec("envmap", name, str(path), rotation_deg=90.0,
                                                scale=normalised_scale(base))))


@pytest.mark.parametrize("kind", PROCEDURAL_KINDS)
def test_diffuse_sphere_under_procedural_map_matches_cosine_convolution(kind):
    params = sample_params(kind, np.random.default_rng(2))
    base = procedural_map(kind, params)
    _check_diffuse_sphere(build_light(LightSpec(kind, kind, "", rotation_deg=90.0, scale=normalised_scale(base),
                                                params=params)))


@pytest.mark.parametrize("az, el", [(300.0, 30.0), (90.0, -25.0)])
def test_diffuse_sphere_under_olat_light_matches_cosine_convolution(az, el):
    # One small disc (3 degrees): the lit half follows the cosine law, the other half is black, the terminator sharp.
    params = olat_params(az, el, 3.0)
    _check_diffuse_sphere(build_light(LightSpec("olat", "olat", "", rotation_deg=0.0, scale=olat_scale(params),
                                                params=params)))


def _check_diffuse_sphere(light):
    name = light.spec.name
    cam = Camera(width=48, height=48, fov_y_deg=30.0, origin=(0.3, -4.0, 0.5), target=(0.0, 0.0, 0.0))
    # max_depth 2 = direct light only, which for a convex object is the whole answer (it never sees itself).
    out = render_frame([uv_sphere(albedo=ALBEDO, n_lat=96, n_lon=192)], mitsuba_emitter_dict(light), cam,
                       RenderSettings(spp=512, aov_spp=16, max_depth=2), ["image", "mask", "normal"], seed=11)
    inside = out.layers["mask"] > 0.999
    n_world = out.layers["normal"][inside] @ cam.world_to_opengl_rotation()  # R^T applied row-wise
    # Irradiance is the cosine convolution of the map: a low-pass filter, so a 4x box-downsampled map gives it
    # to well under the Monte Carlo noise while keeping the test fast.
    world_map = downsample_equirect(light.world_radiance(), 4)
    expected = luminance(ALBEDO * brute_force_irradiance(world_map, n_world) / np.pi)
    got = luminance(out.layers["image"][inside])
    resid = got - expected
    se = resid.std() / np.sqrt(resid.size)
    assert abs(resid.mean()) < 4 * se + 0.01 * expected.mean(), (name, resid.mean(), se, expected.mean())
    # Per pixel, the median relative deviation is Monte Carlo noise at 512 spp: a few percent.
    assert np.median(np.abs(resid) / np.maximum(expected, 1e-6)) < 0.08, name
