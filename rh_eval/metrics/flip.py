"""LDR-FLIP (Andersson et al. 2020) through NVIDIA's `flip_evaluator` at a fixed, reported pixels-per-degree.

`flip_evaluator.evaluate` calls sys.exit(1) on bad arguments and silently accepts out-of-range LDR input, so every
argument is validated here first and the [0, 1] inputs are clipped (a no-op on validated input, kept against
round-off). Inputs are display-space sRGB. Identical inputs give 0. With a mask: the per-pixel FLIP map averaged
over the mask (NaN for an empty mask); without one, FLIP's own mean.
"""
from __future__ import annotations

import math

import numpy as np

from ._validate import _validate, _validate_mask

__all__ = ["flip", "flip_map", "FLIP_PPD", "flip_version"]

# FLIP's default viewing condition (0.7 m from a 0.7 m wide 3840-pixel monitor) as the float32 FLIP reports.
FLIP_PPD = 67.02064514160156


def flip_version() -> str:
    from importlib.metadata import version
    return version("flip-evaluator")


def _check_ppd(ppd) -> float:
    if isinstance(ppd, bool) or not isinstance(ppd, (int, float, np.floating, np.integer)) \
            or not math.isfinite(ppd) or ppd <= 0:
        raise ValueError(f"flip: ppd must be a positive finite number, got {ppd!r}")
    return float(ppd)


def _run(p: np.ndarray, t: np.ndarray, data_range: float, ppd: float):
    import flip_evaluator

    ref = np.ascontiguousarray(np.clip(t / data_range, 0.0, 1.0), dtype=np.float32)
    test = np.ascontiguousarray(np.clip(p / data_range, 0.0, 1.0), dtype=np.float32)
    err, mean, _params = flip_evaluator.evaluate(ref, test, "LDR", inputsRGB=True, applyMagma=False,
                                                 computeMeanError=True, parameters={"ppd": float(ppd)})
    return np.asarray(err, dtype=np.float64).reshape(p.shape[:2]), float(mean)


def flip_map(pred: np.ndarray, target: np.ndarray, *, data_range: float = 1.0, ppd: float = FLIP_PPD) -> np.ndarray:
    """The (H, W) LDR-FLIP error map, values in [0, 1]."""
    p, t = _validate(pred, target, data_range=data_range, name="flip")
    return _run(p, t, data_range, _check_ppd(ppd))[0]


def flip(pred: np.ndarray, target: np.ndarray, *, data_range: float = 1.0, mask: np.ndarray | None = None,
         ppd: float = FLIP_PPD) -> float:
    """Mean LDR-FLIP error of `pred` against the reference `target`, (H, W, 3) in [0, data_range]."""
    p, t = _validate(pred, target, data_range=data_range, name="flip")
    m = _validate_mask(mask, p.shape[:2], name="flip")
    ppd = _check_ppd(ppd)
    if m is not None and not m.any():
        return float("nan")
    err, mean = _run(p, t, data_range, ppd)
    return mean if m is None else float(err[m].mean())
