"""SSIM as Wang et al. 2004: Gaussian window sigma 1.5 (11x11, scikit-image truncates at 3.5 sigma), K1 0.01,
K2 0.03, population (not sample) covariance, fixed data range, computed per channel and averaged.

This is `skimage.metrics.structural_similarity(target, pred, gaussian_weights=True, sigma=1.5,
use_sample_covariance=False, data_range=R, channel_axis=-1)` on float64 inputs, whose mean leaves out the 5-pixel
border where the window does not fit. With a mask: the full SSIM map (channel mean) averaged over the mask's
pixels, with the same 5-pixel border left out. An empty mask (after removing the border) gives NaN.

`window="uniform7"` is scikit-image's own default instead (7x7 uniform window, sample covariance, 3-pixel border
left out), which published code that calls `structural_similarity(a, b, ...)` without window arguments computes
(rh_eval.conventions: intrinsicavatar, relightableavatar); it departs from Wang et al.'s definition.
"""
from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

from ._validate import _validate, _validate_mask

__all__ = ["ssim", "ssim_map", "SSIM_SIGMA", "SSIM_K1", "SSIM_K2", "SSIM_BORDER"]

SSIM_SIGMA = 1.5
SSIM_K1 = 0.01
SSIM_K2 = 0.03
SSIM_BORDER = 5  # (win_size - 1) // 2 with win_size = 2 * int(3.5 * 1.5 + 0.5) + 1 = 11


WINDOWS = {"gaussian11": SSIM_BORDER, "uniform7": 3}  # window -> border where it does not fit


def _skimage_ssim(p: np.ndarray, t: np.ndarray, data_range: float, full: bool, window: str = "gaussian11"):
    if window not in WINDOWS:
        raise ValueError(f"ssim: window must be one of {sorted(WINDOWS)}, got {window!r}")
    b = WINDOWS[window]
    if min(p.shape[:2]) < 2 * b + 1:
        raise ValueError(f"ssim: images must be at least {2 * b + 1}x{2 * b + 1}, got {p.shape}")
    if window == "uniform7":
        return structural_similarity(t, p, win_size=7, K1=SSIM_K1, K2=SSIM_K2, data_range=float(data_range),
                                     channel_axis=-1, full=full)
    return structural_similarity(t, p, gaussian_weights=True, sigma=SSIM_SIGMA, use_sample_covariance=False,
                                 K1=SSIM_K1, K2=SSIM_K2, data_range=float(data_range), channel_axis=-1, full=full)


def ssim_map(pred: np.ndarray, target: np.ndarray, *, data_range: float = 1.0) -> np.ndarray:
    """The (H, W) SSIM map (mean over channels); its 5-pixel border is not meaningful."""
    p, t = _validate(pred, target, data_range=data_range, name="ssim")
    _, s = _skimage_ssim(p, t, data_range, full=True)
    return s.mean(axis=-1)


def ssim(pred: np.ndarray, target: np.ndarray, *, data_range: float = 1.0, mask: np.ndarray | None = None,
         window: str = "gaussian11") -> float:
    """Mean SSIM of `pred` against `target`, (H, W, C) floats in [0, data_range]; 1 for identical inputs.
    `window`: gaussian11 (Wang et al. 2004, the default) or uniform7 (scikit-image's defaults)."""
    p, t = _validate(pred, target, data_range=data_range, name="ssim")
    m = _validate_mask(mask, p.shape[:2], name="ssim")
    if m is None:
        return float(_skimage_ssim(p, t, data_range, full=False, window=window))
    _, s = _skimage_ssim(p, t, data_range, full=True, window=window)
    inner = np.zeros_like(m)
    b = WINDOWS[window]
    inner[b:-b, b:-b] = m[b:-b, b:-b]
    if not inner.any():
        return float("nan")
    return float(s.mean(axis=-1)[inner].mean())
