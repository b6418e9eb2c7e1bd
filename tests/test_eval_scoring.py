"""One scoring path: the public per-frame scorer gives rh-eval's numbers, and the batched network metrics (with the
reference as images or as cached features) give the per-image numbers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rh_eval import Convention, FrameGroundTruth, FramePrediction, read_frame, score_frame
from rh_eval.dataset_io import load_dataset, scan_predictions
from rh_eval.evaluate import EvalOptions, Evaluator
from rh_eval.metrics import dists, dists_features, lpips, lpips_features
from rh_eval.scoring import NETWORK_METRICS
from test_eval_fake import make_dataset, make_predictions


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("ds") / "data", empty_mask=("subject_001", 1))


@pytest.fixture(scope="module")
def noisy(ds, tmp_path_factory):
    return make_predictions(ds, tmp_path_factory.mktemp("pred") / "noisy", name="noisy", noise=0.05, fmt="png",
                            albedo_scale=0.8)


def _per_frame(pred, ds, conv, metrics):
    idx = scan_predictions(pred, load_dataset(ds, "a"))
    return [{"subject": f.gt.subject, "frame": f.gt.index,
             **score_frame(*read_frame(f, metrics), conv, metrics).columns()} for f in idx.frames]


@pytest.mark.parametrize("region", ["default", "full", "mask"])
def test_score_frame_gives_rh_evals_numbers(ds, noisy, region):
    conv = Convention(region=region, align_albedo=True)
    metrics = ("lpips", "dists", "ssim", "psnr", "flip", "normal")
    _, rows, cols = Evaluator(EvalOptions(convention=conv, metrics=metrics, progress=False)).evaluate(noisy, ds)
    mine = _per_frame(noisy, ds, conv, metrics)
    assert [set(r) for r in mine] == [set(r) for r in rows]
    assert any(r["empty_mask"] for r in rows) and "normal_deg" in cols and "albedo_aligned_lpips" in cols
    for a, b in zip(rows, mine):
        for k, v in a.items():
            if k.endswith(NETWORK_METRICS) and v is not None:
                # rh-eval batches crops of several frames: oneDNN's kernels vary with the batch size
                assert b[k] == pytest.approx(v, abs=1e-6), k
            else:
                assert b[k] == v, k


def test_one_frame_batched_alike_is_bit_identical(tmp_path):
    """A frame's three crops (image, albedo, aligned albedo) are one batch in both: the same bits."""
    ds = make_dataset(tmp_path / "ds", subjects=("subject_000",), frames=(0,))
    pred = make_predictions(ds, tmp_path / "p", noise=0.05)
    conv = Convention(align_albedo=True)
    _, rows, _ = Evaluator(EvalOptions(convention=conv, progress=False)).evaluate(pred, ds)
    assert rows == _per_frame(pred, ds, conv, ("lpips", "dists", "ssim", "psnr", "flip", "normal"))


def test_score_frame_on_arrays():
    rng = np.random.default_rng(3)
    mask = np.zeros((80, 80), np.uint8)
    mask[20:60, 25:55] = 255
    img = rng.uniform(0, 2, (80, 80, 3)).astype(np.float32)
    gt = FrameGroundTruth(mask=mask, exposure=0.5, image=img)
    same = score_frame(FramePrediction(image=img.copy()), gt)
    assert same.compared == ("image",) and not same.empty_mask
    assert same.image.psnr == math.inf and same.image.ssim == 1.0
    assert same.image.lpips == 0.0 and same.image.dists == 0.0 and same.image.flip == 0.0
    worse = score_frame(FramePrediction(image=img * 1.2), gt, metrics=("psnr", "lpips"))
    assert 0 < worse.image.lpips and worse.image.psnr < 40 and worse.image.ssim is None
    assert set(worse.columns()) == {"empty_mask", "image_psnr", "image_lpips"}
    empty = score_frame(FramePrediction(image=img), FrameGroundTruth(mask=np.zeros_like(mask), exposure=0.5,
                                                                     image=img), metrics=("psnr",))
    assert empty.empty_mask and empty.image.psnr is None  # undefined, as rh-eval stores it


def test_frame_inputs_are_checked():
    mask = np.full((32, 32), 255, np.uint8)
    img = np.zeros((32, 32, 3), np.float32)
    with pytest.raises(ValueError, match="uint8"):
        FrameGroundTruth(mask=mask / 255.0, exposure=1.0, image=img)
    with pytest.raises(ValueError, match="exposure"):
        FrameGroundTruth(mask=mask, exposure=0.0, image=img)
    with pytest.raises(ValueError, match="32x32x3"):
        FrameGroundTruth(mask=mask, exposure=1.0, image=img[..., :2])
    with pytest.raises(ValueError, match="float or uint8"):
        FramePrediction(image=img.astype(np.int32))
    gt = FrameGroundTruth(mask=mask, exposure=1.0, image=img)
    with pytest.raises(ValueError, match="albedo"):  # the prediction has a layer the ground truth lacks
        score_frame(FramePrediction(image=img, albedo=img), gt, metrics=("psnr",))
    with pytest.raises(ValueError, match="16x16"):
        score_frame(FramePrediction(image=img[:16, :16]), gt, metrics=("psnr",))
    with pytest.raises(ValueError, match="unknown metric"):
        score_frame(FramePrediction(image=img), gt, metrics=("psnr", "mse"))


def _batch(rng, n=3, size=48):
    yy, xx = np.mgrid[0:size, 0:size] / size
    xs = np.stack([np.clip(np.dstack([0.5 + 0.4 * np.sin((6 + i) * xx), 0.5 + 0.3 * np.cos(5 * yy), 0.3 + xx * yy])
                           + 0.05 * rng.standard_normal((size, size, 3)), 0, 1) for i in range(n)])
    return np.clip(xs + 0.1 * rng.standard_normal(xs.shape), 0, 1), xs


@pytest.mark.parametrize("fn,features", [(lpips, lpips_features), (dists, dists_features)])
def test_batched_network_metric_is_the_per_image_metric(fn, features):
    ys, xs = _batch(np.random.default_rng(7))
    batch = fn(ys, xs)
    assert batch.shape == (3,) and batch.dtype == np.float64
    for i in range(3):
        assert batch[i] == pytest.approx(fn(ys[i], xs[i]), abs=1e-6)
    # a list is the stacked batch; the reference's features stand for the reference, to the bit
    assert np.array_equal(fn(list(ys), list(xs)), batch)
    assert np.array_equal(fn(ys, target_features=features(xs)), batch)
    assert fn(ys[0], target_features=features(xs[0])) == fn(ys[0], xs[0])


@pytest.mark.parametrize("fn,features", [(lpips, lpips_features), (dists, dists_features)])
def test_reference_features_are_checked(fn, features):
    ys, xs = _batch(np.random.default_rng(8))
    with pytest.raises(ValueError, match="either target or target_features"):
        fn(ys, xs, target_features=features(xs))
    with pytest.raises(ValueError, match="either target or target_features"):
        fn(ys)
    with pytest.raises(ValueError, match="do not match"):  # one reference against three: no silent broadcast
        fn(ys, target_features=features(xs[:1]))
    with pytest.raises(ValueError, match="one shape"):
        fn([ys[0], ys[1][:40]], [xs[0], xs[1][:40]])
    with pytest.raises(ValueError, match="outside"):
        features(xs * 2.0)
