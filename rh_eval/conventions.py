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

Named conventions (`CONVENTIONS`, `named_convention`): `rana` (the default above), `intrinsicavatar` and
`relightableavatar`, each a bundle of every field below reproducing that method's own evaluation code
(docs/EVALUATION.md, "Named conventions", says what each does and where it departs from the metric's reference
definition). Their extra regions: `box100` (the bounding box of the mask dilated by OpenCV with a 100x100 kernel:
49 px before and 50 px after the mask on each axis, in pixels at any resolution) and, for albedo,
`albedo_region="mask_box"` (the tight box of the mask, PSNR over mask pixels, SSIM and LPIPS on the whole crop, the
prediction zeroed outside the mask and the ground truth as it is).
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field

import numpy as np

from rh_common.colourspace import srgb_encode

__all__ = [
    "Convention",
    "CONVENTIONS",
    "named_convention",
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
    "gt_albedo_values",
    "ALIGNMENTS",
]

REGIONS = ("default", "full", "mask", "box100")
ALIGNMENTS = ("none", "lsq", "median")
SSIM_WINDOWS = ("gaussian11", "uniform7")
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
    align_albedo: str = "none"
    """none | lsq | median: also report `albedo_aligned_*`, the linear prediction scaled per channel onto the linear
    ground truth over the mask (least squares, or the median of ground truth / prediction), clipped to [0, 1]."""
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
    name: str = "rana"
    """The named bundle these fields came from (`CONVENTIONS`); flags that override a field keep the name and are
    recorded in the fields themselves."""
    composite: str = "both"
    """both: prediction and ground truth composited over `background` (default, mask, box100 regions); gt: only the
    ground truth, the prediction compared as rendered (its own background), also in the full region."""
    alpha: str = "coverage"
    """coverage: the ground-truth coverage / 255 is the compositing alpha; binary: coverage >= mask_threshold."""
    min_crop: int = MIN_CROP
    """A crop smaller than this on a side is grown, centred (0: never grown)."""
    ssim_window: str = "gaussian11"
    """gaussian11: Wang et al. 2004 (Gaussian sigma 1.5, population covariance); uniform7: scikit-image's default
    (7x7 uniform window, sample covariance)."""
    ssim_data_range: float = 1.0
    """The data range SSIM's constants are computed with (2.0: what scikit-image <= 0.19 took for float input)."""
    lpips_normalize: bool = True
    """True: [0, 1] images mapped to LPIPS's [-1, 1] input range (the official `normalize=True`); False: the [0, 1]
    values fed as they are (`lpips.LPIPS()(a, b)` without normalize)."""
    albedo_gt: str = "linear"
    """linear: the ground-truth albedo as stored (`_albedo.exr`); srgb_as_linear: its sRGB encoding (the values of
    `_albedo.png`, unquantised) treated as linear values."""
    albedo_region: str = "same"
    """same: albedo uses the image region; mask_box: the tight box of the mask, PSNR over mask pixels, SSIM/LPIPS on
    the whole crop, the prediction zeroed outside the mask, the ground truth as it is."""
    align_image: str = "none"
    """none | median: also report `image_aligned_*`, the display-space image scaled per channel by the median of
    ground truth / prediction over the mask, clipped to [0, 1]."""
    relit_with_aligned_albedo: bool = False
    """The predicted relit images are expected to be rendered with the aligned albedo (a rule for the submission:
    rh-eval cannot re-render; recorded so that a reader knows which images were asked for)."""
    normal_mask: str = "gt"
    """gt: normals compared inside the ground-truth mask; gt_and_pred: inside the mask and where the predicted
    normal has non-zero length."""
    normal_frame: str = "opengl_camera"
    """Normals compared in camera axes, OpenGL convention (x right, y up, z toward the camera; ARCHITECTURE.md)."""
    resampling: str = "none"
    """none: predictions must be at the ground truth's resolution. area: a prediction may be smaller; the ground
    truth is brought to its size first (images, albedo, normals area-averaged, the mask by nearest neighbour:
    RelightableAvatar's loader, `scoring.resample_ground_truth`)."""

    def __post_init__(self) -> None:
        if isinstance(self.align_albedo, bool):  # result files before the named conventions recorded a bool
            object.__setattr__(self, "align_albedo", "lsq" if self.align_albedo else "none")
        for fld, allowed in (("align_albedo", ALIGNMENTS), ("align_image", ("none", "median")),
                             ("composite", ("both", "gt")), ("alpha", ("coverage", "binary")),
                             ("ssim_window", SSIM_WINDOWS), ("albedo_gt", ("linear", "srgb_as_linear")),
                             ("albedo_region", ("same", "mask_box")), ("normal_mask", ("gt", "gt_and_pred")),
                             ("resampling", ("none", "area")),
                             ("name", tuple(CONVENTIONS))):
            if getattr(self, fld) not in allowed:
                raise ValueError(f"{fld} must be one of {allowed}, got {getattr(self, fld)!r}")
        if not (isinstance(self.ssim_data_range, (int, float)) and self.ssim_data_range > 0):
            raise ValueError(f"ssim_data_range must be positive, got {self.ssim_data_range!r}")
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

    @classmethod
    def from_json(cls, d: dict) -> "Convention":
        """A result file's convention; fields it lacks (files written before they existed) take the defaults,
        which are what those files were computed with."""
        known = {f for f in cls.__dataclass_fields__}
        return cls(**{k: v for k, v in d.items() if k in known})

    def region_key(self) -> str:
        """A short hash of what changes the ground truth's pixels fed to the networks (the feature cache key)."""
        d = {k: v for k, v in self.to_json().items() if k in ("region", "background", "albedo_space", "image_space",
                                                              "gt_image", "margin_rule", "mask_threshold")}
        # fields added with the named conventions enter the key only where they differ from `rana`, so that
        # rana's keys (and an existing disk cache) stay what they were
        base = Convention()
        for k in ("composite", "alpha", "min_crop", "lpips_normalize", "albedo_gt", "albedo_region"):
            if getattr(self, k) != getattr(base, k):
                d[k] = getattr(self, k)
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
    psnr_mask: np.ndarray | None = None  # (h, w) bool: PSNR alone over these pixels (albedo_region mask_box)
    composite_pred: bool = True  # composite the prediction (False: compared as rendered)
    composite_gt: bool = True
    background: tuple | None = None  # None: the convention's background

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


def _box(inside: np.ndarray) -> tuple[int, int, int, int]:
    rows = np.flatnonzero(inside.any(axis=1))
    cols = np.flatnonzero(inside.any(axis=0))
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


def compute_region(mask_u8: np.ndarray, conv: Convention, layer: str = "image") -> Region:
    """The region of a frame's `layer` (image, albedo), from its ground-truth coverage (uint8 (H, W))."""
    if mask_u8.ndim != 2:
        raise ValueError(f"mask must be (H, W), got {mask_u8.shape}")
    h, w = mask_u8.shape
    inside = mask_u8 >= conv.mask_threshold
    if layer == "albedo" and conv.albedo_region == "mask_box":
        if not inside.any():
            return Region(0, h, 0, w, None, None, empty=True)
        y0, y1, x0, x1 = _box(inside)
        y0, y1 = _grow(y0, y1, h, conv.min_crop)
        x0, x1 = _grow(x0, x1, w, conv.min_crop)
        m = inside[y0:y1, x0:x1]
        return Region(y0, y1, x0, x1, m.astype(np.float64), None, psnr_mask=m.copy(), composite_gt=False,
                      background=BACKGROUNDS["black"])
    gt_only = conv.composite == "gt"
    if conv.region == "full":
        if not gt_only:
            return Region(0, h, 0, w, None, None)
        if not inside.any():
            return Region(0, h, 0, w, None, None, empty=True)
        y0, y1, x0, x1 = 0, h, 0, w
    else:
        if not inside.any():
            return Region(0, h, 0, w, None, None, empty=True)
        y0, y1, x0, x1 = _box(inside)
        if conv.region == "default":
            m = margin_for(h, w)
            y0, y1, x0, x1 = max(0, y0 - m), min(h, y1 + m), max(0, x0 - m), min(w, x1 + m)
        elif conv.region == "box100":
            # cv2.dilate with np.ones((100, 100)) anchors the kernel at (50, 50): a mask pixel spreads 49 px up and
            # left and 50 px down and right; cv2.boundingRect of the result
            y0, y1, x0, x1 = max(0, y0 - 49), min(h, y1 + 50), max(0, x0 - 49), min(w, x1 + 50)
        y0, y1 = _grow(y0, y1, h, conv.min_crop)
        x0, x1 = _grow(x0, x1, w, conv.min_crop)
    if conv.alpha == "binary":
        alpha = inside[y0:y1, x0:x1].astype(np.float64)
    else:
        alpha = mask_u8[y0:y1, x0:x1].astype(np.float64) / 255.0
    metric_mask = inside[y0:y1, x0:x1].copy() if conv.region == "mask" else None
    return Region(y0, y1, x0, x1, alpha, metric_mask, composite_pred=not gt_only)


def apply_region(img: np.ndarray, region: Region, conv: Convention, who: str = "gt") -> np.ndarray:
    """Crop (H, W, 3) `img` to the region and composite it over the background; float64 in [0, 1]."""
    return composite(img[region.y0:region.y1, region.x0:region.x1], region, conv, who)


def composite(crop: np.ndarray, region: Region, conv: Convention, who: str = "gt") -> np.ndarray:
    """An image already cropped to `region`, composited over the background (`who`: pred or gt, each composited
    only where the region says so); float64 in [0, 1]."""
    crop = np.asarray(crop, dtype=np.float64)
    if region.alpha is None or not (region.composite_pred if who == "pred" else region.composite_gt):
        return crop
    bg = np.asarray(region.background or BACKGROUNDS[conv.background], dtype=np.float64)
    a = region.alpha[..., None]
    return np.clip(a * crop + (1.0 - a) * bg, 0.0, 1.0)


def align_albedo(pred_linear: np.ndarray, gt_linear: np.ndarray, inside: np.ndarray,
                 method: str = "lsq") -> tuple[np.ndarray, list]:
    """Per-channel scale of `pred_linear` onto `gt_linear` over `inside`, then clip to [0, 1]: `lsq`
    s_c = sum(p g) / sum(p p), `median` s_c = median(g / p) over the pixels with p > 0.

    Returns the aligned albedo and the three scales (a channel with nothing to divide by keeps scale 1; an empty
    mask keeps every scale 1). Also used for relit images (`Convention.align_image`)."""
    if method not in ("lsq", "median"):
        raise ValueError(f"alignment must be 'lsq' or 'median', got {method!r}")
    p = np.asarray(pred_linear, dtype=np.float64)
    g = np.asarray(gt_linear, dtype=np.float64)
    scales = []
    for c in range(3):
        pc, gc = p[..., c][inside], g[..., c][inside]
        if method == "lsq":
            den = float(np.dot(pc, pc))
            scales.append(float(np.dot(pc, gc)) / den if den > 0 else 1.0)
        else:
            pos = pc > 0
            scales.append(float(np.median(gc[pos] / pc[pos])) if pos.any() else 1.0)
    out = np.clip(p * np.asarray(scales)[None, None, :], 0.0, 1.0)
    return out, scales


def albedo_to_space(albedo_linear: np.ndarray, conv: Convention) -> np.ndarray:
    a = np.clip(np.asarray(albedo_linear, dtype=np.float64), 0.0, 1.0)
    return srgb_encode(a).astype(np.float64) if conv.albedo_space == "srgb" else a


def gt_albedo_values(gt_linear: np.ndarray, conv: Convention) -> np.ndarray:
    """The ground-truth albedo as the convention reads it: linear, or (`albedo_gt="srgb_as_linear"`) the values of
    its sRGB encoding taken as linear (IntrinsicAvatar reads the albedo PNG as linear)."""
    if conv.albedo_gt == "srgb_as_linear":
        return srgb_encode(np.clip(np.asarray(gt_linear, dtype=np.float64), 0.0, 1.0)).astype(np.float64)
    return gt_linear


# Every choice of each published evaluation, from its own code (docs/EVALUATION.md, "Named conventions", gives the
# files and commits, and where each departs from the metric's reference definition). Fields not named: `rana`'s.
CONVENTIONS: dict[str, dict] = {
    "rana": {},
    # taconite/IntrinsicAvatar @ d243d20: datasets/rana.py (100x100 dilation, binary mask, GT over white),
    # systems/criterions.py (PSNR over the box, skimage 0.18.1 SSIM defaults on the crop, LPIPS-VGG normalize=True),
    # systems/intrinsic_avatar.py + models/utils.py (per-channel lsq albedo, clamped, relit with it)
    "intrinsicavatar": dict(region="box100", composite="gt", alpha="binary", background="white", min_crop=0,
                            ssim_window="uniform7", ssim_data_range=2.0, backbone="vgg", lpips_normalize=True,
                            albedo_space="linear", albedo_gt="srgb_as_linear", albedo_region="mask_box",
                            align_albedo="lsq", relit_with_aligned_albedo=True),
    # zju3dv/RelightableAvatar @ 3504fde: lib/evaluators/base_evaluator.py (eval_whole_img, bg_brightness 0, GT
    # background zeroed by its mask, skimage SSIM data_range=1, lpips.LPIPS() = AlexNet without normalize);
    # albedo (median), relit-image alignment and the normal mask follow the paper (not in the released code);
    # lib/datasets/base_dataset.py get_image_and_mask: the GT shrunk by cfg.ratio (INTER_AREA image, INTER_NEAREST mask)
    "relightableavatar": dict(region="full", composite="gt", alpha="binary", background="black", min_crop=0,
                              ssim_window="uniform7", ssim_data_range=1.0, backbone="alex", lpips_normalize=False,
                              albedo_space="linear", albedo_region="mask_box", align_albedo="median",
                              align_image="median", normal_mask="gt_and_pred", resampling="area"),
}


def named_convention(name: str, **overrides) -> Convention:
    """The convention `name` (`CONVENTIONS`), with `overrides` (None values ignored) on top."""
    if name not in CONVENTIONS:
        raise ValueError(f"unknown convention {name!r}; known conventions: {', '.join(CONVENTIONS)}")
    fields = dict(CONVENTIONS[name], name=name)
    fields.update({k: v for k, v in overrides.items() if v is not None})
    return Convention(**fields)
