"""Resampling images to another size: exact area (box) averaging for colours and vectors, nearest for masks.

In: an (H, W[, C]) array and the size wanted. Out: the array at that size. Used where a named convention evaluates
at a smaller size than the ground truth (`resampling="area"`: RelightableAvatar's loader shrinks the ground truth
by `cfg.ratio` with OpenCV's INTER_AREA for images and INTER_NEAREST for masks before its network renders at that
size) and by the leaderboard's thumbnails.

`shrink_area` averages each output pixel's footprint in the input, weighting the input pixels it covers in part by
the covered fraction: OpenCV's INTER_AREA for a downscale (for an integer factor, the plain block mean).
`shrink_nearest` takes input pixel floor(i · H/h) for output pixel i, as OpenCV's INTER_NEAREST does.
"""
from __future__ import annotations

import numpy as np

__all__ = ["area_matrix", "shrink_area", "shrink_nearest"]


def area_matrix(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) weights averaging each output pixel's footprint (exact box/area resampling)."""
    if not (0 < n_out <= n_in):
        raise ValueError(f"area resampling shrinks: {n_in} px cannot become {n_out} px")
    edges = np.arange(n_out + 1) * (n_in / n_out)
    lo, hi = edges[:-1, None], edges[1:, None]
    px = np.arange(n_in)[None, :]
    w = np.clip(np.minimum(hi, px + 1) - np.maximum(lo, px), 0.0, None)
    return w / w.sum(axis=1, keepdims=True)


def shrink_area(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """`img` (H, W[, C]) area-averaged to `size` = (h, w), float64 (unchanged, as given, when the size is equal)."""
    h, w = img.shape[:2]
    if (h, w) == tuple(size):
        return img
    ry, rx = area_matrix(h, size[0]), area_matrix(w, size[1])
    x = np.asarray(img, dtype=np.float64).reshape(h, w, -1)
    rows = (ry @ x.reshape(h, -1)).reshape(size[0], w, -1)  # two matrix products (a 3-operand einsum loops naively)
    return (rows.transpose(0, 2, 1) @ rx.T).transpose(0, 2, 1).reshape(tuple(size) + img.shape[2:])


def shrink_nearest(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """`img` (H, W[, C]) at `size` = (h, w) by nearest neighbour, pixel floor(i · H/h), dtype kept."""
    h, w = img.shape[:2]
    if not (0 < size[0] <= h and 0 < size[1] <= w):
        raise ValueError(f"nearest resampling here shrinks: {w}x{h} cannot become {size[1]}x{size[0]}")
    ys = np.minimum(np.floor(np.arange(size[0]) * (h / size[0])).astype(np.int64), h - 1)
    xs = np.minimum(np.floor(np.arange(size[1]) * (w / size[1])).astype(np.int64), w - 1)
    return img[ys][:, xs]
