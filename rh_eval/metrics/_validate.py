"""The one input check every metric runs first. Raises ValueError (never assert: asserts vanish under -O)."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["_validate", "_validate_mask", "_stack", "_deep_inputs"]


def _validate(pred, target, *, data_range: float | None, name: str, channels: int | None = 3,
              batch: bool = False, value_range: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Check a (pred, target) pair and return them as float64 arrays (`target` None: `pred` alone, returned with None).

    - numpy arrays of a floating dtype (an integer array is refused: forgetting /255 is the classic bug);
    - the same shape, (H, W, C) or, with `batch`, also (N, H, W, C), with C == `channels` when given;
    - every value finite;
    - every value inside `value_range` (default [0, data_range]) when a data range is given.
    """
    alone = target is None
    if alone:  # one set of images (the network metrics' reference features): checked as a pair with itself
        target = pred
    for label, arr in (("pred", pred), ("target", target)):
        if not isinstance(arr, np.ndarray):
            raise ValueError(f"{name}: {label} must be a numpy array, got {type(arr).__name__}")
        if not np.issubdtype(arr.dtype, np.floating):
            raise ValueError(f"{name}: {label} must be a float array (scale integers to [0, data_range] first), "
                             f"got dtype {arr.dtype}")
    if pred.shape != target.shape:
        raise ValueError(f"{name}: pred shape {pred.shape} != target shape {target.shape}")
    ndims = (3, 4) if batch else (3,)
    if pred.ndim not in ndims:
        want = "(H, W, C) or (N, H, W, C)" if batch else "(H, W, C)"
        raise ValueError(f"{name}: expected {want}, got shape {pred.shape}")
    if channels is not None and pred.shape[-1] != channels:
        raise ValueError(f"{name}: expected {channels} channels, got {pred.shape[-1]} (shape {pred.shape})")
    if min(pred.shape[-3:-1]) < 1:
        raise ValueError(f"{name}: empty image of shape {pred.shape}")
    if data_range is not None:
        if not (isinstance(data_range, (int, float, np.floating, np.integer)) and math.isfinite(data_range)
                and data_range > 0):
            raise ValueError(f"{name}: data_range must be a positive finite number, got {data_range!r}")
    p = np.asarray(pred, dtype=np.float64)
    t = p if alone else np.asarray(target, dtype=np.float64)
    checked = (("pred", p),) if alone else (("pred", p), ("target", t))
    for label, arr in checked:
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name}: {label} contains NaN or Inf")
    lo_hi = value_range if value_range is not None else ((0.0, float(data_range)) if data_range is not None else None)
    if lo_hi is not None:
        lo, hi = lo_hi
        for label, arr in checked:
            amin, amax = float(arr.min()), float(arr.max())
            if amin < lo or amax > hi:
                raise ValueError(f"{name}: {label} values span [{amin:.6g}, {amax:.6g}], outside [{lo:g}, {hi:g}]")
    return p, (None if alone else t)


def _validate_mask(mask, shape_hw: tuple[int, int], *, name: str) -> np.ndarray | None:
    """None, or a boolean (H, W) array matching the image."""
    if mask is None:
        return None
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
        raise ValueError(f"{name}: mask must be a boolean numpy array (threshold coverage first), "
                         f"got {type(mask).__name__} {getattr(mask, 'dtype', '')}")
    if mask.shape != tuple(shape_hw):
        raise ValueError(f"{name}: mask shape {mask.shape} != image (H, W) {tuple(shape_hw)}")
    return mask


def _stack(images, *, name: str, label: str):
    """A list or tuple of equal-shape (H, W, C) arrays as one (N, H, W, C) array; anything else as it is (checked by
    `_validate`). The network metrics take either, so a caller with separate crops need not stack them itself."""
    if not isinstance(images, (list, tuple)):
        return images
    if not images:
        raise ValueError(f"{name}: {label} is an empty list")
    shapes = {getattr(a, "shape", None) for a in images}
    if len(shapes) != 1 or any(not isinstance(a, np.ndarray) or a.ndim != 3 for a in images):
        raise ValueError(f"{name}: a {label} list must hold (H, W, C) numpy arrays of one shape, got shapes "
                         f"{sorted(map(str, shapes))}")
    return np.stack(images)


def _deep_inputs(pred, target, target_features, mask, *, data_range: float, name: str):
    """The one input check of the network metrics (LPIPS, DISTS): a rectangle (no mask), the reference as images or
    as precomputed features but not both, `pred` as one image or a batch. Returns (single, pred batch, target batch
    or None when `target_features` are given)."""
    if mask is not None:
        raise ValueError(f"{name}: a mask is not supported ({name.upper()} is defined on a rectangle); crop and "
                         "composite with rh_eval.conventions first")
    if (target is None) == (target_features is None):
        raise ValueError(f"{name}: give either target or target_features")
    single = isinstance(pred, np.ndarray) and pred.ndim == 3
    pred = _stack(pred, name=name, label="pred")
    if target_features is None:
        p, t = _validate(pred, _stack(target, name=name, label="target"), data_range=data_range, name=name,
                         batch=True)
        return single, p, t
    p, _ = _validate(pred, None, data_range=data_range, name=name, batch=True)
    return single, p, None
