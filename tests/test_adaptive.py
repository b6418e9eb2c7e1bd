"""Samples by noise (rh_dataset.render.adaptive): the allocation's arithmetic, the display-space noise, and the
invariant that the adaptive beauty image is an unbiased estimate of the same image a full-frame render estimates."""
from __future__ import annotations

import numpy as np
import pytest

from analytic_scenes import deep_sphere_reference, gradient_env, sphere_camera, uv_sphere
from rh_common.colourspace import srgb_encode_reference
from rh_dataset.render.adaptive import allocate, check_tiers, display_noise
from rh_dataset.render.focus import person_pixels
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant

TIERS = (16, 36, 64, 100, 144, 256)


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


def test_neyman_allocation_is_proportional_to_the_noise_s_deviation():
    # Two groups whose deviations differ 4x: Neyman gives them counts 4x apart, here exactly two tiers, mean = budget.
    noise = np.array([1.0] * 50 + [16.0] * 50)
    t = allocate(noise, 62.5, (25, 100))
    assert np.all(t[:50] == 0) and np.all(t[50:] == 1)


def test_allocation_respects_the_budget_order_floor_and_cap(rng):
    noise = rng.lognormal(0.0, 2.0, 5000)
    t = allocate(noise, 99, TIERS)
    counts = np.asarray(TIERS)[t]
    assert 90 < counts.mean() <= 99
    order = np.argsort(noise, kind="stable")
    assert np.all(np.diff(t[order]) >= 0)  # more noise, never fewer samples
    assert t.min() == 0 and t.max() == len(TIERS) - 1
    noise[:10] = 0.0  # no measured noise: the first tier
    assert np.all(allocate(noise, 99, TIERS)[:10] == 0)
    assert np.all(allocate(np.zeros(7), 99, TIERS) == 0)
    assert len(allocate(np.zeros(0), 99, TIERS)) == 0
    # equal noise: one tier for everyone, the largest within the budget
    assert set(np.asarray(TIERS)[allocate(np.ones(100), 99, TIERS)]) == {64}
    assert set(np.asarray(TIERS)[allocate(np.ones(100), 256, TIERS)]) == {256}


def test_display_noise_is_the_delta_method_through_srgb_and_coverage():
    # one channel lit (mean m, per-sample variance v), the others black and noiseless
    m, v, n = 0.25, 0.01, 4
    mean = np.array([[m, 0.0, 0.0]] * 4)
    second = np.array([[m * m + v * (n - 1) / n, 0.0, 0.0]] * 4)
    cov = np.array([1.0, 0.5, 0.0, 1.0])
    exposure = np.array([1.0, 1.0, 1.0, 8.0])  # the last pixel is clipped: e m = 2 > 1
    got = [display_noise(mean[i:i + 1], second[i:i + 1], n, cov[i:i + 1], float(exposure[i]))[0] for i in range(4)]
    h = 1e-5
    slope = (srgb_encode_reference(m + h) - srgb_encode_reference(m - h)) / (2 * h)  # the sRGB curve (float64)
    assert got[0] == pytest.approx(slope ** 2 * v, rel=1e-6)
    assert got[1] == pytest.approx(0.25 * slope ** 2 * v, rel=1e-6)
    assert got[2] == 0.0 and got[3] == 0.0
    toe = display_noise(np.array([[1e-4, 0, 0]]), np.array([[1e-8 + 1e-6 * 3 / 4, 0, 0]]), 4, np.ones(1), 1.0)[0]
    assert toe == pytest.approx(12.92 ** 2 * 1e-6)
    with pytest.raises(ValueError, match="at least 2 samples"):
        display_noise(mean, second, 1, cov, 1.0)


def test_tiers_are_checked_with_a_one_line_error():
    assert check_tiers([16, 64], 32, 4) == (16, 64)
    for bad, spp, env, msg in [((64, 16), 32, 4, "increasing"), ((16,), 16, 4, "two or more"),
                               ((16, 64), 99, 4, r"within \[16, 64\]"), ((16, 64), 32, 1, "env_spp >= 2"),
                               ((16, 64), 32, None, "env_spp >= 2"), (("16", 64), 32, 4, "integers")]:
        with pytest.raises(ValueError, match=msg):
            check_tiers(bad, spp, env)
    with pytest.raises(ValueError, match=r"spp=99 is the mean count"):
        RenderSettings(spp=99, env_spp=4, adaptive_tiers=(16, 64))
    assert RenderSettings(spp=32, env_spp=4, adaptive_tiers=[16, 64]).adaptive_tiers == (16, 64)


def test_adaptive_beauty_is_an_unbiased_estimate_of_the_full_frame_image():
    # As tests/test_focus.py: a deep full-frame reference (16 x 256 independent spp) and K adaptive frames, each an
    # independent estimate; if both estimate the same image, the mean squared difference of the adaptive mean to the
    # reference equals the sum of their variances (ratio ~1), a bias would add to the numerator only. The frames'
    # spread includes the allocation's own randomness (each frame's pilot differs), as it must.
    env, cam, sphere, r, var_r = deep_sphere_reference()
    st = RenderSettings(spp=16, aov_spp=4, max_depth=3, env_spp=4, sampler="multijitter", adaptive_tiers=(4, 16, 36))
    runs = [render_frame(sphere, env, cam, st, ["image", "mask"], seed=1000 + 7 * k, exposure=1.0) for k in range(16)]
    tiers = runs[0].info["focus"]["pixels_per_tier"]
    assert sum(1 for v in tiers.values() if v > 0) >= 2 and runs[0].info["focus"]["pixels"] > 50  # really adaptive
    x = np.array([run.layers["image"] for run in runs], dtype=np.float64)
    m, var_m = x.mean(axis=0), x.var(axis=0, ddof=1) / len(x)
    sel = np.zeros(cam.width * cam.height, bool)
    sel[person_pixels(runs[0].layers["mask"], 2).astype(int)] = True
    sel = sel.reshape(cam.height, cam.width)
    for where in (sel, ~sel):
        ratio = np.mean((m - r)[where] ** 2) / np.mean((var_m + var_r)[where])
        assert 0.5 < ratio < 1.6, ratio
    # determinism: the same seed gives the same bits and the same allocation
    again = render_frame(sphere, env, cam, st, ["image", "mask"], seed=1000, exposure=1.0)
    assert np.array_equal(again.layers["image"], runs[0].layers["image"])
    assert again.info["focus"] == runs[0].info["focus"]


def test_adaptive_needs_the_exposure():
    st = RenderSettings(spp=16, aov_spp=4, max_depth=3, env_spp=4, sampler="multijitter", adaptive_tiers=(4, 36))
    with pytest.raises(ValueError, match="exposure"):
        render_frame([uv_sphere()], gradient_env(), sphere_camera(8), st, ["image", "mask"], seed=0)


def test_a_presets_file_takes_adaptive_tiers_and_refuses_bad_ones(tmp_path):
    import json

    from rh_dataset.presets import load_presets
    from rh_dataset.scene_files import SCENES_DIR, SpecError

    data = json.loads((SCENES_DIR / "presets.json").read_text())
    data["presets"]["standard"]["adaptive_tiers"] = [16, 64, 256]
    path = tmp_path / "presets.json"
    path.write_text(json.dumps(data))
    assert load_presets(path)["standard"].adaptive_tiers == (16, 64, 256)
    data["presets"]["standard"]["adaptive_tiers"] = [16, 64]
    path.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=r"preset standard: render setting spp=\d+ is the mean count"):
        load_presets(path)
