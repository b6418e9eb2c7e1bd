"""The evaluation conventions: which region of a frame is compared, over which background, in which colour space,
and the optional albedo alignment. Every result file records the `Convention` it was computed with.

Regions (`region`):

- `default` (the published protocol for this dataset): the bounding box of the ground-truth mask (coverage >= 128)
  dilated by `margin` pixels on every side (clipped to the frame), with prediction and ground truth both
  composited over one fixed background using the ground-truth coverage as alpha (`a * img + (1 - a) * bg`). The
  published evaluation uses a 100x100 dilation kernel (50 px each side) at 720 px image height; the margin here
  scales with resolution: `margin = round(50 * min(H, W) / 720)` (36 px at 512x512). Every metric is computed on
  the whole box.
- `full`: the whole frame as is (no compositing).
- `mask`: composited as in `default`, cropped to the tight (undilated) bounding box; PSNR, SSIM and FLIP are
  averaged over the mask's pixels only, LPIPS and DISTS (defined on rectangles) run on the tight crop.

A crop smaller than `MIN_CROP` (64 px) on a side is grown, centred, to 64 px (or the frame size), so that the
networks and SSIM's 11x11 window always fit. An empty ground-truth mask leaves `default` and `mask` undefined for
that frame (its image and albedo metrics are null and counted, never averaged); `full` still evaluates it.
Normals are always compared inside the ground-truth mask, whatever the region.

Colour: images are compared in display space, `srgb_encode(clip(exposure * radiance, 0, 1))` with the ground-truth
frame's exposure (ARCHITECTURE.md). Albedo (`albedo_space`): `srgb` (default; linear albedo sRGB-encoded, as the
`_albedo.png` files are and as perceptual networks expect) or `linear`. Albedo alignment (`align_albedo`): a
per-channel least-squares scale of the linear prediction onto the linear ground truth over the mask,
`s_c = sum(p g) / sum(p p)`, then clipped to [0, 1]; aligned scores are reported beside the raw ones, never
instead of them.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field

import numpy as np

from rh_common.colourspace import srgb_encode

__all__ = [
    "Convention",
    "Region",
    "REGIONS",
    "BACKGROUNDS",
    "MIN_CROP",
    "margin_for",
    "compute_region",
    "apply_region",
    "composite",
    "align_albedo",
    "albedo_to_space",
]

REGIONS = ("default", "full", "mask")
BACKGROUNDS = {"white": (1.0, 1.0, 1.0), "black": (0.0, 0.0, 0.0), "grey": (0.5, 0.5, 0.5)}
MIN_CROP = 64
PUBLISHED_MARGIN_PX = 50  # 100x100 dilation kernel
PUBLISHED_SHORT_SIDE = 720  # published test camera 1280x720
MASK_THRESHOLD = 128  # "inside the person" = coverage >= 128 (ARCHITECTURE.md, Masks)


@dataclass(frozen=True)
class Convention:
    """Everything that changes a score besides the two images. Recorded in every result file."""

    region: str = "default"
    """default | full | mask (see module docstring)."""
    background: str = "white"
    """Background the prediction and ground truth are composited over (default and mask regions)."""
    albedo_space: str = "srgb"
    """srgb | linear: the space albedo is compared in."""
    align_albedo: bool = False
    """Also report albedo scores after a per-channel least-squares scale (reported separately)."""
    backbone: str = "alex"
    """LPIPS backbone: alex (default, as the official package) | vgg."""
    flip_ppd: float = 67.02064514160156
    """FLIP pixels per degree (FLIP's default viewing condition)."""
    image_space: str = "display"
    """Images are compared in display space: sRGB(clip(exposure * radiance, 0, 1))."""
    gt_image: str = "exr"
    """Ground-truth image source: the linear EXR brought to display space (not the quantised PNG preview)."""
    margin_rule: str = field(default="round(50 * min(H, W) / 720)")
    mask_threshold: int = MASK_THRESHOLD

    def __post_init__(self) -> None:
        if self.region not in REGIONS:
            raise ValueError(f"region must be one of {REGIONS}, got {self.region!r}")
        if self.background not in BACKGROUNDS:
            raise ValueError(f"background must be one of {sorted(BACKGROUNDS)}, got {self.background!r}")
        if self.albedo_space not in ("srgb", "linear"):
            raise ValueError(f"albedo_space must be 'srgb' or 'linear', got {self.albedo_space!r}")
        if self.backbone not in ("alex", "vgg"):
            raise ValueError(f"backbone must be 'alex' or 'vgg', got {self.backbone!r}")
        if isinstance(self.flip_ppd, bool) or not isinstance(self.flip_ppd, (int, float, np.integer, np.floating)) \
                or not (np.isfinite(self.flip_ppd) and self.flip_ppd > 0):
            raise ValueError(f"flip_ppd must be positive and finite, got {self.flip_ppd!r}")

    def to_json(self) -> dict:
        return asdict(self)

    def region_key(self) -> str:
        """A short hash of what changes the pixels fed to the metrics (for the ground-truth feature cache)."""
        d = {k: v for k, v in self.to_json().items() if k in ("region", "background", "albedo_space", "image_space",
                                                              "gt_image", "margin_rule", "mask_threshold")}
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Region:
    """A crop (y0:y1, x0:x1) of the frame, the coverage inside it, and the metric mask (None = whole crop)."""

    y0: int
    y1: int
    x0: int
    x1: int
    alpha: np.ndarray | None  # (h, w) float coverage in [0, 1] for compositing, None = no compositing
    metric_mask: np.ndarray | None  # (h, w) bool, None = the whole crop
    empty: bool = False

    @property
    def shape(self) -> tuple[int, int]:
        return (self.y1 - self.y0, self.x1 - self.x0)


def margin_for(height: int, width: int) -> int:
    return int(round(PUBLISHED_MARGIN_PX * min(height, width) / PUBLISHED_SHORT_SIDE))


def _grow(lo: int, hi: int, size: int, minimum: int) -> tuple[int, int]:
    want = min(minimum, size)
    if hi - lo >= want:
        return lo, hi
    c = (lo + hi) / 2.0
    lo = int(np.floor(c - want / 2.0))
    lo = max(0, min(lo, size - want))
    return lo, lo + want


def compute_region(mask_u8: np.ndarray, conv: Convention) -> Region:
    """The region of a frame, from its ground-truth coverage (uint8 (H, W))."""
    if mask_u8.ndim != 2:
        raise ValueError(f"mask must be (H, W), got {mask_u8.shape}")
    h, w = mask_u8.shape
    if conv.region == "full":
        return Region(0, h, 0, w, None, None)
    inside = mask_u8 >= conv.mask_threshold
    if not inside.any():
        return Region(0, h, 0, w, None, None, empty=True)
    rows = np.flatnonzero(inside.any(axis=1))
    cols = np.flatnonzero(inside.any(axis=0))
    y0, y1, x0, x1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    if conv.region == "default":
        m = margin_for(h, w)
        y0, y1, x0, x1 = max(0, y0 - m), min(h, y1 + m), max(0, x0 - m), min(w, x1 + m)
    y0, y1 = _grow(y0, y1, h, MIN_CROP)
    x0, x1 = _grow(x0, x1, w, MIN_CROP)
    alpha = mask_u8[y0:y1, x0:x1].astype(np.float64) / 255.0
    metric_mask = inside[y0:y1, x0:x1].copy() if conv.region == "mask" else None
    return Region(y0, y1, x0, x1, alpha, metric_mask)


def apply_region(img: np.ndarray, region: Region, conv: Convention) -> np.ndarray:
    """Crop (H, W, 3) `img` to the region and composite it over the background; float64 in [0, 1]."""
    return composite(img[region.y0:region.y1, region.x0:region.x1], region, conv)


def composite(crop: np.ndarray, region: Region, conv: Convention) -> np.ndarray:
    """An image already cropped to `region`, composited over the background; float64 in [0, 1]."""
    crop = np.asarray(crop, dtype=np.float64)
    if region.alpha is None:
        return crop
    bg = np.asarray(BACKGROUNDS[conv.background], dtype=np.float64)
    a = region.alpha[..., None]
    return np.clip(a * crop + (1.0 - a) * bg, 0.0, 1.0)


def align_albedo(pred_linear: np.ndarray, gt_linear: np.ndarray, inside: np.ndarray) -> tuple[np.ndarray, list]:
    """Per-channel least-squares scale of `pred_linear` onto `gt_linear` over `inside`, then clip to [0, 1].

    Returns the aligned albedo and the three scales (a channel with sum(p p) = 0 keeps scale 1; an empty mask keeps
    every scale 1)."""
    p = np.asarray(pred_linear, dtype=np.float64)
    g = np.asarray(gt_linear, dtype=np.float64)
    scales = []
    for c in range(3):
        pc, gc = p[..., c][inside], g[..., c][inside]
        den = float(np.dot(pc, pc))
        scales.append(float(np.dot(pc, gc)) / den if den > 0 else 1.0)
    out = np.clip(p * np.asarray(scales)[None, None, :], 0.0, 1.0)
    return out, scales


def albedo_to_space(albedo_linear: np.ndarray, conv: Convention) -> np.ndarray:
    a = np.clip(np.asarray(albedo_linear, dtype=np.float64), 0.0, 1.0)
    return srgb_encode(a).astype(np.float64) if conv.albedo_space == "srgb" else a
