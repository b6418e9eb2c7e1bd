"""Numerical stability at the extremes (issue 5): lights, exposure, poses, cameras, resolutions and metrics.

Every case ends in a defined, documented result or a clear error; docs/TRADEOFFS.md ("Extremes") lists them.
Tiny resolutions and few samples: the whole file runs in well under two minutes (the 2048x2048 case is AOV-only at
1 spp).
"""
from __future__ import annotations

import math
import types

import numpy as np
import pytest

from analytic_scenes import uv_sphere
from rh_common import sh
from rh_common.colourspace import quantize8, to_display
from rh_common.imageio import read_exr, read_json, read_png, write_exr
from rh_dataset.generate import exposure_for
from rh_dataset.lights import LightSpec, build_light, load_hdri, mitsuba_emitter_dict, normalised_scale
from rh_common.camera import Camera
from rh_dataset.render.passes import FIREFLY_K, count_fireflies, render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant
from rh_dataset.writer import write_frame

ALL = ["image", "mask", "albedo", "normal", "depth"]


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


def _light_from_map(tmp_path, name: str, radiance: np.ndarray, rotation_deg: float = 0.0, scale: float = 1.0):
    path = tmp_path / f"{name}.exr"
    write_exr(path, radiance.astype(np.float32))
    return build_light(LightSpec("envmap", name, str(path), rotation_deg, scale))


def _cam(w=16, h=16, dist=4.0, fov=40.0, origin=None, target=(0.0, 0.0, 0.0)) -> Camera:
    return Camera(width=w, height=h, fov_y_deg=fov, origin=origin or (0.0, -dist, 0.0), target=target)


def _check_aovs(layers: dict) -> None:
    """Every layer finite; normals unit inside the mask and exactly 0 outside; albedo in [0, 1]."""
    for k, v in layers.items():
        assert np.all(np.isfinite(v)), k
    if "normal" in layers:
        n = layers["normal"]
        length = np.linalg.norm(n, axis=-1)
        inside = layers["mask"] > 1e-6 if "mask" in layers else length > 0
        assert np.allclose(length[inside], 1.0, atol=1e-4)
        assert np.all(n[length == 0] == 0)
    if "albedo" in layers:
        assert layers["albedo"].min() >= 0 and layers["albedo"].max() <= 1


def _meta(exposure: float, layers: dict) -> dict:
    h, w = next(iter(layers.values())).shape[:2]
    return {"subject": "subject_000", "protocol": "a", "split": "test", "width": w, "height": h,
            "exposure": exposure, "render": {"spp": 1, "denoised": False}}


# ------------------------------------------------------------------------------------------------ lights

def test_a_1e5_radiance_sun_renders_finite_and_float32_exr_keeps_it_exactly(tmp_path):
    env = np.full((16, 32, 3), 0.5, np.float32)
    env[5, 10] = (1e5, 9e4, 7e4)  # above half-float's 65504
    light = _light_from_map(tmp_path, "sun", env)
    assert light.radiance.max() == np.float32(1e5)
    exposure = exposure_for(light)
    assert math.isfinite(exposure) and exposure > 0
    out = render_frame([uv_sphere(albedo=(0.5, 0.5, 0.5))], mitsuba_emitter_dict(light), _cam(),
                       RenderSettings(spp=8, aov_spp=2, max_depth=3), ALL, seed=0)
    _check_aovs(out.layers)
    assert out.layers["image"].min() >= 0
    # The writer's float32 EXR round trip is bit-exact above 65504 (half would give inf).
    img = out.layers["image"].copy()
    img[0, 0] = (1e5, 65504.0 * 1.5, 123456.789)
    json_path = write_frame(tmp_path / "f", 0, {"image": img, "mask": out.layers["mask"]}, _meta(exposure, out.layers))
    back = read_exr(tmp_path / "f" / "frame_000000_image.exr")
    assert back.dtype == np.float32 and np.array_equal(back, img)
    assert read_json(json_path)["render"]["fireflies"] >= 0


def test_an_all_black_hdri_gives_a_black_beauty_exposure_1_and_files_that_write(tmp_path):
    light = _light_from_map(tmp_path, "black", np.zeros((16, 32, 3), np.float32))
    # Documented fallback: exposure_for returns 1.0 when the map's mean luminance is <= 1e-12 (no division by 0).
    assert exposure_for(light) == 1.0
    # ... but an all-black map cannot be normalised: the sampler's normalised_scale refuses it with a clear error.
    with pytest.raises(ValueError, match="all-black"):
        normalised_scale(light.radiance)
    np.testing.assert_array_equal(light.sh_world, 0.0)
    out = render_frame([uv_sphere()], mitsuba_emitter_dict(light), _cam(), RenderSettings(spp=4, aov_spp=2, max_depth=4),
                       ALL, seed=0)
    assert np.all(out.layers["image"] == 0.0)
    assert out.layers["mask"].max() == 1.0  # coverage does not depend on the light
    _check_aovs(out.layers)
    assert count_fireflies(out.layers["image"]) == 0
    np.testing.assert_array_equal(to_display(out.layers["image"], 1.0), 0.0)
    write_frame(tmp_path / "f", 0, out.layers, _meta(exposure_for(light), out.layers))
    assert read_png(tmp_path / "f" / "frame_000000_image.png").max() == 0
    assert read_json(tmp_path / "f" / "frame_000000.json")["render"]["fireflies"] == 0


def test_a_constant_hdri_has_only_the_dc_sh_term_and_renders_without_fireflies(tmp_path):
    L = 2.0
    light = _light_from_map(tmp_path, "const", np.full((16, 32, 3), L, np.float32))
    assert exposure_for(light) == pytest.approx(1.0 / L, rel=1e-5)
    np.testing.assert_allclose(light.sh_world[1:], 0.0, atol=1e-5)
    n = sh.fibonacci_sphere(64)
    np.testing.assert_allclose(sh.shading(light.sh_world, n), L, rtol=1e-5)  # S = E / pi = L
    out = render_frame([uv_sphere(albedo=(0.5, 0.5, 0.5))], mitsuba_emitter_dict(light), _cam(w=32, h=32),
                       RenderSettings(spp=16, aov_spp=2, max_depth=2), ["image", "mask"], seed=2)
    inside = out.layers["mask"] > 0.999
    assert abs(out.layers["image"][inside].mean() - 0.5 * L) < 0.02 * L
    assert count_fireflies(out.layers["image"]) == 0


def test_tiny_negative_pixels_are_clamped_to_zero_and_counted(tmp_path):
    env = np.full((8, 16, 3), 0.3, np.float32)
    env[2, 3, 0] = -1e-4
    env[4, 7, :] = -2e-6
    path = tmp_path / "neg.exr"
    write_exr(path, env)
    radiance, clamped = load_hdri(path)
    assert clamped == 4 and radiance.min() == 0.0
    assert radiance[2, 3, 0] == 0.0 and np.all(radiance[4, 7] == 0.0)
    assert build_light(LightSpec("envmap", "neg", str(path), 0.0, 1.0)).negative_pixels_clamped == 4


def test_a_single_pixel_light_makes_raw_sh_shading_negative_and_the_oracle_clamps_it(tmp_path):
    from rana.oracle import oracle_image

    env = np.zeros((32, 64, 3), np.float32)
    env[16, 20] = 1000.0  # one pixel just below the horizon
    light = _light_from_map(tmp_path, "dot", env)
    n = sh.fibonacci_sphere(2000)
    s = sh.shading(light.sh_world, n)[:, 0]
    # Documented: rh_common.sh.shading returns the raw order-2 value. For a (near-)point light it is the truncated
    # clamped-cosine kernel K2(t) = 1/4 + t/2 + 5/32 (3t^2 - 1), whose minimum (t = -8/15) over its maximum (t = 1)
    # is -0.0396 / 1.0625 = -3.7 %.
    k2 = lambda t: 0.25 + t / 2 + 5 / 32 * (3 * t * t - 1)  # noqa: E731
    assert s.min() < 0
    assert s.min() / s.max() == pytest.approx(k2(-8 / 15) / k2(1.0), rel=0.05)
    # The oracle bound (rana/oracle.py) clamps shading at 0: a pixel whose normal sees negative SH is black.
    normals = n[None, :, :].astype(np.float32)
    albedo = np.full_like(normals, 0.5)
    img = oracle_image(albedo, normals, light.sh_world, np.zeros_like(normals))
    assert img.min() >= 0.0
    np.testing.assert_array_equal(img[0, s < 0], 0.0)
    np.testing.assert_allclose(img[0, s > 0, 0], 0.5 * s[s > 0], rtol=1e-5, atol=1e-7)  # float32 output


def test_exposure_extremes_stay_finite_or_raise():
    rad = np.array([[[0.0, 1e-30, 1e5]]], np.float32)
    for e in (1e-30, 1e-6, 1.0, 1e6, 1e30):
        d = to_display(rad, e)
        assert np.all(np.isfinite(d)) and d.min() >= 0 and d.max() <= 1
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="exposure"):
            to_display(rad, bad)
    # exposure_for: 1 / mean luminance; a mean at or below 1e-12 falls back to 1.0 (documented).
    envmap = types.SimpleNamespace(kind="envmap")
    dim = types.SimpleNamespace(radiance=np.full((8, 16, 3), 1e-6, np.float32), spec=envmap)
    assert exposure_for(dim) == pytest.approx(1e6, rel=1e-4)
    very_dim = types.SimpleNamespace(radiance=np.full((8, 16, 3), 1e-13, np.float32), spec=envmap)
    assert exposure_for(very_dim) == 1.0


def test_an_exposure_beyond_float32_range_is_refused():
    # 1e39 is finite in float64 but inf in float32, where 0 * inf would give NaN: refused, not propagated.
    with pytest.raises(ValueError, match="float32 range"):
        to_display(np.zeros((1, 1, 3), np.float32), 1e39)
    assert np.all(np.isfinite(to_display(np.zeros((1, 1, 3), np.float32), 1e38)))


# ------------------------------------------------------------------------------------------------ fireflies

def test_firefly_count_definition():
    flat = np.full((20, 20, 3), 0.2, np.float32)
    assert count_fireflies(flat) == 0
    assert count_fireflies(np.zeros_like(flat)) == 0
    one = flat.copy()
    one[7, 9] = 0.2 * FIREFLY_K * 1.01
    assert count_fireflies(one) == 1
    below = flat.copy()
    below[7, 9] = 0.2 * FIREFLY_K * 0.99
    assert count_fireflies(below) == 0
    black = np.zeros_like(flat)
    black[3, 3] = 1e-3
    assert count_fireflies(black) == 1  # a lone pixel on black: the local median is 0
    cluster = flat.copy()
    cluster[5:7, 5:7] = 50.0  # 4 of 25 neighbours: the median is untouched
    assert count_fireflies(cluster) == 4
    disc = flat.copy()
    disc[4:13, 4:13] = 50.0  # a 9x9 bright disc (a sun seen directly) is not noise: only pixels near its edge count
    assert 0 < count_fireflies(disc) < 81
    with pytest.raises(ValueError, match="NaN"):
        count_fireflies(np.full((4, 4, 3), np.nan, np.float32))


def test_firefly_count_equals_a_full_median_filter():
    # count_fireflies takes medians only where the window's minimum lets a pixel count: the same count as the
    # definition's median filter over the whole frame (scipy, edges reflected), on heavy-tailed noise and edges.
    from scipy.ndimage import median_filter

    rng = np.random.default_rng(3)
    edge = np.zeros((40, 50, 3))
    edge[:, 25:] = rng.gamma(0.5, 1.0, (40, 25, 3))
    edge[0, 0] = edge[39, 49] = 2.0  # lone pixels in the corners: the reflected edges decide them
    for img in (rng.pareto(1.1, (60, 70, 3)), rng.gamma(0.2, 1.0, (33, 47, 3)), edge):
        for window in (3, 4, 5):
            lum = img @ np.array([0.2126, 0.7152, 0.0722])
            want = np.count_nonzero(lum > FIREFLY_K * np.maximum(median_filter(lum, size=window, mode="reflect"),
                                                                  1e-4 * lum.mean()))
            assert count_fireflies(img, window=window) == want > 0


def test_the_writer_records_fireflies_and_never_clamps_them(tmp_path):
    img = np.full((12, 12, 3), 0.1, np.float32)
    img[3, 4] = 500.0
    img[8, 8] = 80.0
    write_frame(tmp_path, 0, {"image": img}, _meta(1.0, {"image": img}))
    meta = read_json(tmp_path / "frame_000000.json")
    assert meta["render"]["fireflies"] == 2 and meta["render"]["denoised"] is False
    np.testing.assert_array_equal(read_exr(tmp_path / "frame_000000_image.exr"), img)


# ------------------------------------------------------------------------------------------------ geometry / camera

@pytest.fixture(scope="module")
def character():
    from rh_dataset.characters import build_character, sample_recipe
    from rh_dataset.generate import rng_for

    return build_character(sample_recipe(rng_for(0, "character", 0), pool="benchmark", index=0), drape="coarse")


def _extreme_poses():
    from rh_common.body_model import load_anny
    from rh_dataset.poses import joint_specs, pose_from_angles, rig_for

    specs = joint_specs(rig_for(load_anny()))
    squat = {}
    for s in ("L", "R"):
        squat[f"upperleg01.{s}"] = (120.0, 20.0, 0.0)  # joint limits: hip flexion 120, knee 145, ankle 20
        squat[f"lowerleg01.{s}"] = (145.0, 0.0, 0.0)
        squat[f"foot.{s}"] = (20.0, 0.0, 0.0)
    overhead = {f"upperarm01.{s}": (170.0, 0.0, 0.0) for s in ("L", "R")}
    overhead.update({f"lowerarm01.{s}": (0.0, 0.0, 0.0) for s in ("L", "R")})
    twisted = {"root": (80.0, 20.0, 180.0), **{f"upperarm01.{s}": (-45.0, 170.0, 80.0) for s in ("L", "R")},
               **{f"lowerarm01.{s}": (145.0, 0.0, 0.0) for s in ("L", "R")}}
    return {name: pose_from_angles(a, specs, label=name)
            for name, a in (("deep-squat", squat), ("arms-overhead", overhead), ("limits", twisted))}


def test_extreme_legal_poses_give_finite_unit_normals(character):
    from rh_dataset.characters import pose_character
    from rh_dataset.render.scene import is_strands

    for name, pose in _extreme_poses().items():
        for m in pose_character(character, dict(pose.bones), pose.root_transform):
            assert np.all(np.isfinite(m.vertices)), (name, m.name)
            if is_strands(m):  # hair: curves carry radii, not vertex normals
                assert np.all(np.isfinite(m.radius)) and np.all(m.radius > 0), (name, m.name)
                continue
            length = np.linalg.norm(m.normals.astype(np.float64), axis=1)
            assert np.all(np.isfinite(m.normals)) and np.allclose(length, 1.0, atol=1e-5), (name, m.name)


def test_an_extreme_pose_renders_finite_layers(character):
    from rh_dataset.characters import body_bounds, pose_character
    from rh_common.camera import frame_body

    pose = _extreme_poses()["deep-squat"]
    meshes = pose_character(character, dict(pose.bones), pose.root_transform)
    cam = frame_body(*body_bounds(meshes), 24, 24, 30.0)
    env = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    out = render_frame(meshes, env, cam, RenderSettings(spp=2, aov_spp=2, max_depth=3), ALL, seed=0)
    _check_aovs(out.layers)
    assert out.layers["mask"].sum() > 20


def test_a_camera_grazing_the_surface_gives_finite_unit_normals():
    # Looking along the tangent plane x = 1 of a unit sphere: the right half of the frame sees it at grazing angles.
    env = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    cam = _cam(w=32, h=32, origin=(1.0, -5.0, 0.0), target=(1.0, 0.0, 0.0))
    out = render_frame([uv_sphere(n_lat=32, n_lon=64)], env, cam, RenderSettings(spp=4, aov_spp=4, max_depth=3),
                       ALL, seed=0)
    _check_aovs(out.layers)
    m = out.layers["mask"]
    assert 0.05 < m.mean() < 0.6


def test_a_body_filling_the_frame_and_a_sub_pixel_one():
    env = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    # camera 2 cm from the surface (near clip 1 cm): the whole frame is the body
    near = render_frame([uv_sphere()], env, _cam(dist=1.02), RenderSettings(spp=2, aov_spp=4, max_depth=3), ALL, 0)
    _check_aovs(near.layers)
    assert np.all(near.layers["mask"] == 1.0)
    # a 15 cm sphere 20 m away covers a tenth of a pixel: coverage is the analytic area (4096 samples per pixel:
    # ~350 hits, 5 % Poisson noise), normals still unit
    cam = _cam(w=16, h=16, dist=20.0)
    f = cam.K[0, 0]
    r = 0.15
    out = render_frame([uv_sphere(radius=r)], env, cam, RenderSettings(spp=1, aov_spp=4096, max_depth=3), ALL, 0)
    _check_aovs(out.layers)
    area_px = math.pi * (r * f / math.sqrt(20.0 ** 2 - r ** 2)) ** 2
    assert area_px < 0.1
    assert out.layers["mask"].sum() == pytest.approx(area_px, rel=0.2)


def test_resolution_16x16_full_frame():
    env = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    out = render_frame([uv_sphere()], env, _cam(), RenderSettings(spp=4, aov_spp=2, max_depth=3), ALL, 0)
    assert all(v.shape[:2] == (16, 16) for v in out.layers.values())
    _check_aovs(out.layers)


def test_resolution_2048x2048_aov_only_at_1_spp():
    env = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}
    cam = _cam(w=2048, h=2048, dist=3.0)
    out = render_frame([uv_sphere(n_lat=32, n_lon=64)], env, cam, RenderSettings(spp=1, aov_spp=1, max_depth=2),
                       ["mask", "normal"], 0)
    assert out.layers["mask"].shape == (2048, 2048)
    _check_aovs(out.layers)
    f = cam.K[0, 0]
    expected = math.pi * (f / math.sqrt(9.0 - 1.0)) ** 2  # the sphere's projected disc (a tangent cone) in pixels
    assert out.layers["mask"].sum() == pytest.approx(expected, rel=0.01)


# ------------------------------------------------------------------------------------------------ metrics

def _imgs(seed=0, shape=(32, 32, 3)):
    r = np.random.default_rng(seed)
    return r.uniform(0, 1, shape), r.uniform(0, 1, shape)


def test_metrics_on_identical_constant_and_black_images():
    from rh_eval.metrics import flip, mse, psnr, ssim

    a, _ = _imgs()
    assert psnr(a, a) == math.inf and mse(a, a) == 0.0 and ssim(a, a) == pytest.approx(1.0) and flip(a, a) == 0.0
    grey, grey2 = np.full((32, 32, 3), 0.5), np.full((32, 32, 3), 0.6)
    assert psnr(grey2, grey) == pytest.approx(20.0)  # 10 log10(1 / 0.01)
    assert ssim(grey, grey) == pytest.approx(1.0)  # constant images: the stabilising constants keep it defined
    assert 0.0 < ssim(grey2, grey) < 1.0
    black, white = np.zeros((32, 32, 3)), np.ones((32, 32, 3))
    assert psnr(black, black) == math.inf and flip(black, black) == 0.0
    assert psnr(black, white) == pytest.approx(0.0)
    assert 0.0 < flip(black, white) <= 1.0


def test_metrics_on_empty_and_one_pixel_masks():
    from rh_eval.metrics import flip, mse, normal_angular_error, psnr, ssim

    a, b = _imgs()
    empty = np.zeros((32, 32), bool)
    for fn in (psnr, mse, ssim, flip):
        assert math.isnan(fn(a, b, mask=empty)), fn.__name__
    assert math.isnan(normal_angular_error(a - 0.5, b - 0.5, mask=empty))
    one = empty.copy()
    one[16, 16] = True
    assert psnr(a, b, mask=one) == pytest.approx(10 * math.log10(1.0 / np.mean((a[16, 16] - b[16, 16]) ** 2)))
    assert math.isfinite(ssim(a, b, mask=one)) and math.isfinite(flip(a, b, mask=one))
    border = empty.copy()
    border[0, 0] = True  # inside SSIM's 5-pixel border: nothing left to average
    assert math.isnan(ssim(a, b, mask=border))
    with pytest.raises(ValueError, match="boolean"):
        psnr(a, b, mask=one.astype(np.uint8))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, -0.01, 1.01])
def test_metrics_refuse_nan_inf_and_out_of_range_predictions(bad):
    from rh_eval.metrics import dists, flip, lpips, mse, psnr, ssim

    a, b = _imgs()
    p = a.copy()
    p[3, 4, 1] = bad
    for fn in (psnr, mse, ssim, flip, lpips, dists):
        with pytest.raises(ValueError, match="NaN or Inf|outside"):
            fn(p, b)


def test_normal_metric_on_zero_and_non_finite_vectors():
    from rh_eval.metrics import normal_angular_error

    t = np.zeros((4, 4, 3))
    t[..., 2] = 1.0
    p = np.zeros_like(t)
    assert normal_angular_error(p, t) == 90.0  # a zero-length prediction has no direction: counted as 90 degrees
    assert normal_angular_error(-t, t) == pytest.approx(180.0)
    p[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN or Inf"):
        normal_angular_error(p, t)


def test_quantize8_of_display_values_is_total():
    x = np.array([-1.0, 0.0, 0.5, 1.0, 2.0])
    np.testing.assert_array_equal(quantize8(x), [0, 0, 128, 255, 255])
