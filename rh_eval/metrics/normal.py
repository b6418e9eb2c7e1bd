"""Mean angular error, in degrees, between predicted and ground-truth normals.

Both inputs are (H, W, 3) float normal vectors already decoded (see `rh_eval.dataset_io`: EXR as stored, PNG as
2 v / 255 - 1); both are renormalised here. The angle is atan2(|a x b|, a . b), accurate near 0 and 180 degrees
(arccos is not). A predicted vector of zero length counts as 90 degrees (it carries no direction). The mean is over
`mask` (default: pixels where the target is non-zero); an empty mask gives NaN.
"""
from __future__ import annotations

import numpy as np

from ._validate import _validate, _validate_mask

__all__ = ["normal_angular_error", "angular_error_map"]


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def angular_error_map(pred: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(H, W) angle in degrees between the renormalised vectors."""
    p, t = _validate(pred, target, data_range=None, name="normal_angular_error")
    a, b = _unit(p), _unit(t)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    ang = np.degrees(np.arctan2(cross, dot))
    degenerate = ~(np.any(a != 0, axis=-1) & np.any(b != 0, axis=-1))
    ang[degenerate] = 90.0  # a zero-length vector has no direction
    return ang


def normal_angular_error(pred: np.ndarray, target: np.ndarray, *, data_range: float | None = None,
                         mask: np.ndarray | None = None) -> float:
    """Mean angle in degrees over `mask` (default: where `target` is non-zero). `data_range` is unused (normals have
    no data range) and accepted for the common metric signature."""
    p, t = _validate(pred, target, data_range=None, name="normal_angular_error")
    m = _validate_mask(mask, p.shape[:2], name="normal_angular_error")
    if m is None:
        m = np.any(t != 0, axis=-1)
    if not m.any():
        return float("nan")
    return float(angular_error_map(p, t)[m].mean())
