"""rh_eval.resample and the `resampling="area"` rule (RelightableAvatar's loader shrinks the ground truth to the
size its network renders at): OpenCV's INTER_AREA and INTER_NEAREST reproduced, and a half-size prediction scored
against the ground truth shrunk the same way."""
from __future__ import annotations

import numpy as np
import pytest

from rh_common.colourspace import to_display
from rh_eval.conventions import named_convention
from rh_eval.resample import shrink_area, shrink_nearest
from rh_eval.scoring import FrameGroundTruth, FramePrediction, prepare_frame, resample_ground_truth

# cv2.resize(np.arange(35, dtype=np.float32).reshape(5, 7) ** 1.5, (4, 3), interpolation=cv2.INTER_AREA) and the
# same for INTER_NEAREST on np.arange(35, dtype=np.uint8).reshape(5, 7), printed by opencv-python-headless 5.0.0
# (PyPI) on 2026-12-02, outside this repository.
CV2_AREA_5x7_TO_3x4 = np.array([[8.36933, 13.024686, 18.9203, 25.753685],
                                [56.79767, 66.750595, 77.25418, 88.27968],
                                [130.6423, 143.85794, 157.4857, 171.5137]])
CV2_NEAREST_5x7_TO_3x4 = np.array([[0, 1, 3, 5], [7, 8, 10, 12], [21, 22, 24, 26]])


def test_area_and_nearest_match_opencv():
    a = np.arange(35, dtype=np.float32).reshape(5, 7) ** 1.5
    np.testing.assert_allclose(shrink_area(a, (3, 4)), CV2_AREA_5x7_TO_3x4, rtol=1e-6)
    assert np.array_equal(shrink_nearest(np.arange(35, dtype=np.uint8).reshape(5, 7), (3, 4)), CV2_NEAREST_5x7_TO_3x4)


def test_shrinking_averages_areas():
    a = np.random.default_rng(0).random((64, 48, 3))
    np.testing.assert_allclose(shrink_area(a, (32, 24)), a.reshape(32, 2, 24, 2, 3).mean(axis=(1, 3)), atol=1e-15)
    b = shrink_area(a, (37, 29))  # a non-integer factor: still a weighted mean of each footprint
    assert b.shape == (37, 29, 3) and abs(b.mean() - a.mean()) < 1e-12
    np.testing.assert_allclose(shrink_area(np.full((50, 30, 1), 0.25), (17, 11)), 0.25, atol=1e-15)
    with pytest.raises(ValueError, match="shrinks"):
        shrink_area(a, (65, 48))


def _gt(h=64, w=48, seed=0):
    rng = np.random.default_rng(seed)
    mask = np.zeros((h, w), np.uint8)
    mask[8:56, 10:40] = 255
    n = rng.normal(size=(h, w, 3))
    return FrameGroundTruth(mask=mask, exposure=1.5, image=(rng.random((h, w, 3)) * 0.6).astype(np.float32),
                            albedo=rng.random((h, w, 3)).astype(np.float32),
                            normal=(n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32))


def test_ground_truth_shrunk_in_display_space():
    gt = _gt()
    half = resample_ground_truth(gt, (32, 24))
    disp = to_display(gt.image, gt.exposure).astype(np.float64)
    # the image is averaged as displayed (their loader averages the 8-bit image's values), not as radiance
    np.testing.assert_allclose(to_display(half.image, half.exposure), disp.reshape(32, 2, 24, 2, 3).mean(axis=(1, 3)),
                               atol=2e-6)
    np.testing.assert_allclose(half.albedo, gt.albedo.reshape(32, 2, 24, 2, 3).mean(axis=(1, 3)), atol=1e-6)
    assert np.array_equal(half.mask, gt.mask[::2, ::2])
    assert resample_ground_truth(gt, (64, 48)) is gt


def test_half_size_prediction_scored_against_the_shrunk_ground_truth():
    gt = _gt()
    half = resample_ground_truth(gt, (32, 24))
    inside = (half.mask >= 128)[..., None]  # the convention zeroes the ground truth's background, not the prediction's
    pred = FramePrediction(image=half.image * inside, albedo=half.albedo, normal=half.normal)
    conv = named_convention("relightableavatar")
    scores, _ = prepare_frame(pred, gt, conv, metrics=("psnr", "ssim", "normal"))
    assert scores.image.psnr > 100 and scores.albedo.psnr > 100 and scores.normal_deg < 1e-3
    with pytest.raises(ValueError, match="is 24x32, the ground truth 48x64"):
        prepare_frame(pred, gt, named_convention("rana"), metrics=("psnr",))
