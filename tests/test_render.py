"""Physics and convention tests of the render stage, on analytic scenes with known answers."""
from __future__ import annotations

import numpy as np
import pytest

from analytic_scenes import quad, uv_sphere
from rh_common.camera import Camera
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


def constant_env(L: float) -> dict:
    return {"type": "constant", "radiance": {"type": "rgb", "value": float(L)}}


def front_camera(w=48, h=48, dist=4.0, fov=40.0) -> Camera:
    return Camera(width=w, height=h, fov_y_deg=fov, origin=(0.0, -dist, 0.0), target=(0.0, 0.0, 0.0))


def test_white_furnace_sphere_returns_the_environment_radiance():
    # A convex albedo-1 Lambertian surface under constant radiance L reflects exactly L: nothing absorbs, and a
    # convex shape never sees itself, so the answer does not depend on the path depth.
    L = 2.5
    cam = front_camera()
    out = render_frame([uv_sphere(radius=1.0)], constant_env(L), cam, RenderSettings(spp=64, aov_spp=4, max_depth=4),
                       ["image", "mask"], seed=1)
    inside = out.layers["mask"] > 0.999
    assert inside.sum() > 500
    vals = out.layers["image"][inside][:, 0].astype(np.float64)
    # Emitter sampling (MIS) gives each pixel Monte Carlo noise; the pixels are independent estimates of L, so
    # their mean must agree with L to within a few standard errors, and no pixel may be far off.
    se = vals.std() / np.sqrt(vals.size)
    assert abs(vals.mean() - L) < 4 * se + 1e-4 * L, (vals.mean(), se)
    assert np.all(np.abs(vals - L) < 6 * vals.std() + 1e-3)


def test_grey_sphere_under_constant_light_renders_albedo_times_radiance():
    L, a = 1.7, np.array([0.2, 0.5, 0.8])
    out = render_frame([uv_sphere(albedo=a)], constant_env(L), front_camera(),
                       RenderSettings(spp=32, aov_spp=4, max_depth=3), ["image", "mask", "albedo"], seed=3)
    inside = out.layers["mask"] > 0.999
    vals = out.layers["image"][inside].astype(np.float64)
    se = vals.std(0) / np.sqrt(len(vals))
    assert np.all(np.abs(vals.mean(0) - a * L) < 4 * se + 1e-4), (vals.mean(0), a * L, se)
    np.testing.assert_allclose(out.layers["albedo"][inside], np.broadcast_to(a, (inside.sum(), 3)), atol=1e-5)


def test_albedo_aov_reproduces_the_texture_and_its_orientation():
    # Texture: top half red, bottom half blue (row 0 = top). UVs are v-up, so the top of the quad must be red.
    tex = np.zeros((8, 8, 3), np.float32)
    tex[:4] = (0.8, 0.1, 0.1)
    tex[4:] = (0.1, 0.1, 0.8)
    q = quad([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], tex)
    cam = front_camera(w=32, h=32, dist=3.0, fov=60.0)
    out = render_frame([q], constant_env(1.0), cam, RenderSettings(spp=4, aov_spp=4, max_depth=2), ["albedo", "mask"],
                       seed=0)
    alb, mask = out.layers["albedo"], out.layers["mask"]
    top = alb[8:13, 12:20][mask[8:13, 12:20] > 0.999]
    bottom = alb[19:24, 12:20][mask[19:24, 12:20] > 0.999]
    np.testing.assert_allclose(top, np.broadcast_to((0.8, 0.1, 0.1), top.shape), atol=1e-5)
    np.testing.assert_allclose(bottom, np.broadcast_to((0.1, 0.1, 0.8), bottom.shape), atol=1e-5)


def test_normals_are_unit_face_the_camera_and_match_the_sphere_analytically():
    cam = front_camera(w=64, h=64)
    out = render_frame([uv_sphere(radius=1.0, n_lat=128, n_lon=256)], constant_env(1.0), cam,
                       RenderSettings(spp=4, aov_spp=16, max_depth=2), ["normal", "mask", "depth"], seed=0)
    n, mask, depth = out.layers["normal"], out.layers["mask"], out.layers["depth"]
    inside = mask > 0.5
    np.testing.assert_allclose(np.linalg.norm(n[inside], axis=-1), 1.0, atol=1e-5)
    assert np.all(n[mask > 0.999][:, 2] > 0.0), "visible normals must face the camera (+z in OpenGL camera axes)"
    assert np.all(n[~(mask > 0)] == 0.0)
    # At the image centre the sphere's normal points straight back at the camera and its depth is dist - r.
    c = n[31:33, 31:33].reshape(-1, 3)
    np.testing.assert_allclose(c, np.broadcast_to((0, 0, 1), c.shape), atol=2e-2)
    np.testing.assert_allclose(depth[31:33, 31:33], 3.0, atol=2e-3)
    # Right half of the image = world +X = OpenGL camera +x; top half = world +Z = camera +y.
    assert n[32, 50, 0] > 0.5 and n[10, 32, 1] > 0.5


def test_mask_is_exact_coverage_of_a_camera_facing_square():
    # A square facing the camera projects to an axis-aligned rectangle whose per-pixel coverage is analytic.
    cam = front_camera(w=40, h=40, dist=5.0, fov=30.0)
    half = 0.47
    q = quad([(-half, 0, -half), (half, 0, -half), (half, 0, half), (-half, 0, half)], np.ones((2, 2, 3)))
    out = render_frame([q], constant_env(1.0), cam, RenderSettings(spp=4, aov_spp=256, max_depth=2), ["mask"], seed=0)
    (u0, v0), (u1, v1) = cam.project(np.array([[-half, 0, half], [half, 0, -half]]))
    cols = np.clip(np.minimum(np.arange(40) + 1, u1) - np.maximum(np.arange(40), u0), 0, 1)
    rows = np.clip(np.minimum(np.arange(40) + 1, v1) - np.maximum(np.arange(40), v0), 0, 1)
    expected = rows[:, None] * cols[None, :]
    err = np.abs(out.layers["mask"] - expected)
    assert err.max() < 0.12  # stochastic edge coverage at 256 spp: sd <= 0.5/16
    assert abs(out.layers["mask"].sum() - expected.sum()) < 0.5


def test_a_rendered_point_lands_where_K_and_world_to_camera_project_it():
    cam = Camera(width=64, height=48, fov_y_deg=35.0, origin=(0.3, -4.0, 0.9), target=(0.1, 0.0, 0.4))
    centre = np.array([0.45, 0.2, 0.65])
    out = render_frame([uv_sphere(center=centre, radius=0.06)], constant_env(1.0), cam,
                       RenderSettings(spp=4, aov_spp=64, max_depth=2), ["mask"], seed=0)
    m = out.layers["mask"]
    ys, xs = np.mgrid[0:48, 0:64]
    cx, cy = (m * (xs + 0.5)).sum() / m.sum(), (m * (ys + 0.5)).sum() / m.sum()
    (pu, pv), = cam.project(centre[None])
    assert abs(cx - pu) < 0.15 and abs(cy - pv) < 0.15


def test_same_seed_gives_bit_identical_layers_and_another_seed_does_not():
    scene = [uv_sphere(albedo=(0.5, 0.4, 0.3))]
    env = constant_env(1.0)
    s = RenderSettings(spp=4, aov_spp=2, max_depth=3)
    a = render_frame(scene, env, front_camera(), s, ["image", "mask", "normal"], seed=7).layers
    b = render_frame(scene, env, front_camera(), s, ["image", "mask", "normal"], seed=7).layers
    c = render_frame(scene, env, front_camera(), s, ["image", "mask", "normal"], seed=8).layers
    for k in a:
        assert np.array_equal(a[k], b[k]), k
    assert not np.array_equal(a["mask"], c["mask"])


def test_only_the_requested_passes_run():
    out = render_frame([uv_sphere()], constant_env(1.0), front_camera(), RenderSettings(spp=2, aov_spp=2, max_depth=2),
                       ["albedo", "mask"], seed=0)
    assert set(out.layers) == {"albedo", "mask"} and set(out.seconds) == {"load", "aov"}
    with pytest.raises(ValueError, match="unknown layers"):
        render_frame([uv_sphere()], constant_env(1.0), front_camera(), RenderSettings(), ["beauty"], seed=0)


def test_high_sample_counts_render_in_chunks_that_average_correctly():
    # 300 spp = a 256-sample chunk and a 44-sample chunk, averaged with weights 256/300 and 44/300.
    from rh_dataset.render.passes import MAX_SPP_PER_CALL

    assert MAX_SPP_PER_CALL < 300
    L = 1.3
    s = RenderSettings(spp=300, aov_spp=2, max_depth=3)
    a = render_frame([uv_sphere()], constant_env(L), front_camera(w=16, h=16), s, ["image", "mask"], seed=5).layers
    b = render_frame([uv_sphere()], constant_env(L), front_camera(w=16, h=16), s, ["image", "mask"], seed=5).layers
    assert np.array_equal(a["image"], b["image"])
    inside = a["mask"] > 0.999
    vals = a["image"][inside][:, 0].astype(np.float64)
    assert abs(vals.mean() - L) < 4 * vals.std() / np.sqrt(vals.size) + 1e-4


def test_specular_materials_keep_the_image_close_to_albedo_times_irradiance():
    # The diffuse base must not be darkened (as a coated plastic's 1/eta^2 would): under uniform light the
    # radiance is albedo * L plus a little specular, and the albedo layer stays exactly the texture colour.
    from analytic_scenes import AnalyticMaterial

    sph = uv_sphere(albedo=(0.4, 0.4, 0.4))
    sph.material = AnalyticMaterial(sph.material.albedo, roughness=0.7, specular=0.5)
    out = render_frame([sph], constant_env(1.0), front_camera(w=32, h=32), RenderSettings(spp=64, aov_spp=4,
                       max_depth=3), ["image", "mask", "albedo"], seed=2).layers
    inside = out["mask"] > 0.999
    ratio = out["image"][inside].mean() / 0.4
    assert 1.0 < ratio < 1.2, ratio
    np.testing.assert_allclose(out["albedo"][inside], 0.4, atol=1e-5)
