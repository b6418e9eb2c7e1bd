"""PSNR = 10 log10(R^2 / MSE), R the fixed data range, MSE over every pixel and channel (or over the mask).

Identical inputs give +inf (returned as float('inf') without a divide-by-zero warning); an empty mask gives NaN.
Without a mask the value is scikit-image's `peak_signal_noise_ratio(target, pred, data_range=R)`.
"""
from __future__ import annotations

import math

import numpy as np
from skimage.metrics import mean_squared_error, peak_signal_noise_ratio

from ._validate import _validate, _validate_mask

__all__ = ["psnr", "mse"]


def mse(pred: np.ndarray, target: np.ndarray, *, data_range: float = 1.0, mask: np.ndarray | None = None) -> float:
    """Mean squared error over all pixels and channels (or over the mask's pixels); NaN for an empty mask."""
    p, t = _validate(pred, target, data_range=data_range, name="mse")
    m = _validate_mask(mask, p.shape[:2], name="mse")
    if m is None:
        return float(mean_squared_error(t, p))
    if not m.any():
        return float("nan")
    return float(np.mean((p[m] - t[m]) ** 2))


def psnr(pred: np.ndarray, target: np.ndarray, *, data_range: float = 1.0, mask: np.ndarray | None = None) -> float:
    """PSNR in dB of `pred` against `target`, both (H, W, C) floats in [0, data_range].

    Returns +inf when the inputs are identical (over the mask), NaN when the mask is empty.
    """
    p, t = _validate(pred, target, data_range=data_range, name="psnr")
    m = _validate_mask(mask, p.shape[:2], name="psnr")
    if m is None:
        err = float(mean_squared_error(t, p))
        if err == 0.0:
            return math.inf
        return float(peak_signal_noise_ratio(t, p, data_range=data_range))
    if not m.any():
        return float("nan")
    err = float(np.mean((p[m] - t[m]) ** 2))
    if err == 0.0:
        return math.inf
    return float(10.0 * np.log10(float(data_range) ** 2 / err))
