"""Samples where the noise is (rh_dataset.render.focus): the pixel-list tracer is Mitsuba's own render on a full
list, and the focused beauty image is an unbiased estimate of the same image a full-frame render estimates."""
from __future__ import annotations

import numpy as np
import pytest

from analytic_scenes import deep_sphere_reference, gradient_env, sphere_camera, uv_sphere
from rh_dataset.render.focus import padded_size, person_pixels, render_pixels
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings, scene_dict
from rh_dataset.variant import load_mitsuba, select_variant


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


@pytest.mark.parametrize("sampler", ["independent", "multijitter"])
def test_render_pixels_on_every_pixel_is_mitsubas_render_bit_for_bit(sampler):
    mi = load_mitsuba()
    cam = sphere_camera(16)
    scene = mi.load_dict(scene_dict([uv_sphere()], gradient_env(), cam, {"type": "path", "max_depth": 3}, 4,
                                    pixel_format="rgba", sampler=sampler))
    full = np.array(mi.render(scene, spp=4, seed=9), dtype=np.float32)[..., :3]
    mine = render_pixels(mi, scene, np.arange(16 * 16, dtype=np.uint32), 4, 9)
    assert np.array_equal(mine.reshape(16, 16, 3), full)
    some = np.array([0, 17, 100, 255], dtype=np.uint32)  # a subset: the same values as those pixels of its own run
    part = render_pixels(mi, scene, some, 4, 9)
    assert part.shape == (4, 3) and np.all(np.isfinite(part))


def test_render_pixels_repeats_its_bits_when_pixels_straddle_drjits_work_blocks():
    # 64 x 64 pixels x 99 spp = 405504 lanes: pixels straddle the 16384-lane blocks drjit's threads take, where a
    # scatter-add into the pixels gave different last bits from run to run (this test failed about every other run).
    mi = load_mitsuba()
    cam = sphere_camera(64)
    scene = mi.load_dict(scene_dict([uv_sphere()], gradient_env(), cam, {"type": "path", "max_depth": 3}, 99,
                                    pixel_format="rgba", sampler="multijitter"))
    pix = np.arange(64 * 64, dtype=np.uint32)
    runs = [render_pixels(mi, scene, pix, 99, 3) for _ in range(3)]
    assert all(np.array_equal(runs[0], r) for r in runs[1:])


def test_person_pixels_grow_the_coverage_and_sizes_pad_to_few_per_octave():
    cov = np.zeros((10, 10))
    cov[5, 5] = 0.3
    assert sorted(person_pixels(cov, 0)) == [55]
    assert len(person_pixels(cov, 1)) == 9 and len(person_pixels(np.zeros((4, 4)), 2)) == 0
    assert padded_size(1) == 1024 and padded_size(1025) == 1280 and padded_size(2049) == 2560
    assert all(padded_size(n) >= n for n in (3000, 70_000, 262_144))


def test_focused_beauty_is_an_unbiased_estimate_of_the_full_frame_image():
    # Reference: the full frame at 16 x 256 spp (independent), the variance of its mean from its chunks. Focused:
    # K frames at spp 16 / env_spp 1, each an independent estimate. If both estimate the same image, the mean
    # squared difference of the focused mean to the reference equals the sum of their variances (ratio ~1); a
    # bias adds to the numerator only.
    env, cam, sphere, r, var_r = deep_sphere_reference()
    st = RenderSettings(spp=16, aov_spp=4, max_depth=3, env_spp=1, sampler="multijitter")
    runs = [render_frame(sphere, env, cam, st, ["image", "mask"], seed=1000 + 7 * k) for k in range(16)]
    assert all(run.info["focus"]["pixels"] > 50 for run in runs)
    x = np.array([run.layers["image"] for run in runs], dtype=np.float64)
    m, var_m = x.mean(axis=0), x.var(axis=0, ddof=1) / len(x)
    person = person_pixels(runs[0].layers["mask"], 2).astype(int)
    sel = np.zeros(cam.width * cam.height, bool)
    sel[person] = True
    sel = sel.reshape(cam.height, cam.width)
    for where in (sel, ~sel):
        ratio = np.mean((m - r)[where] ** 2) / np.mean((var_m + var_r)[where])
        assert 0.5 < ratio < 1.6, ratio
    # The person's pixels really got spp samples and the rest env_spp: their variance against that of a full frame
    # at 1 spp (same sampler) is ~1/16 inside and ~1 outside.
    one = np.array([render_frame(sphere, env, cam, RenderSettings(spp=1, aov_spp=4, max_depth=3, sampler="multijitter"),
                                 ["image"], seed=5000 + k).layers["image"] for k in range(16)], dtype=np.float64)
    v1 = one.var(axis=0, ddof=1)
    v16 = x.var(axis=0, ddof=1)
    assert np.mean(v16[sel]) < np.mean(v1[sel]) / 4
    assert 0.5 < np.mean(v16[~sel]) / np.mean(v1[~sel]) < 2.0 and np.mean(v1[~sel]) > 0
