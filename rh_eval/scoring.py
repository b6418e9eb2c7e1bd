"""One frame's scores, computed exactly as `rh-eval` computes them.

In:  a `FramePrediction` and a `FrameGroundTruth` (numpy arrays as the dataset's and the method's files hold them;
     `read_frame` reads them from a predictions folder), a `Convention` and the metric names.
Out: `FrameScores`: a `LayerScores` per compared layer (image, image_aligned, albedo, albedo_aligned), the normal
     error, the alignment scales, whether the ground-truth mask is empty; `columns()` is the frame's row of
     rh-eval's CSV.

`score_frame` runs two halves, and rh-eval runs the same two: `prepare_frame` (the region, the crops, the colour
conversion, PSNR/SSIM/FLIP and the normal error, and each layer's network inputs as a `NetworkPair`) and
`score_pairs` (LPIPS and DISTS of pairs of one shape, one batch, through the public `rh_eval.metrics.lpips` and
`dists`). rh-eval prepares many frames on worker threads, batches equal-shape pairs of many frames, and hands
`score_pairs` the ground truth's features from its cache. LPIPS/DISTS of a pair can differ in the last bits with
the batch it runs in (oneDNN picks kernels by batch size); every other number is the same bits either way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from rh_common.colourspace import srgb_decode

from .conventions import (Convention, Region, align_albedo, albedo_to_space, composite, compute_region,
                          gt_albedo_values)
from .dataset_io import (PredFrame, albedo_from_stored, decode_layer, display_from_stored, normal_from_stored,
                         read_gt_albedo, read_gt_image_stored, read_gt_mask, read_gt_normal)
from .resample import shrink_area, shrink_nearest
from .metrics import dists, dists_features, flip, lpips, lpips_features, normal_angular_error, psnr, ssim

__all__ = ["ALL_METRICS", "IMAGE_METRICS", "NETWORK_METRICS", "LAYERS", "check_metrics", "FramePrediction",
           "FrameGroundTruth", "LayerScores", "FrameScores", "NetworkPair", "prepare_frame", "score_pairs",
           "record_pair_scores", "score_frame", "read_frame"]

ALL_METRICS = ("lpips", "dists", "ssim", "psnr", "flip", "normal")
IMAGE_METRICS = ("lpips", "dists", "ssim", "psnr", "flip")
NETWORK_METRICS = ("lpips", "dists")
LAYERS = ("image", "image_aligned", "albedo", "albedo_aligned")
_CPU_METRICS = ("psnr", "ssim", "flip")
LPIPS_MIN_SIDE = {"alex": 31, "vgg": 16}  # smaller crops leave no pixel at the backbone's last tap


class CropTooSmallError(ValueError):
    """A crop the LPIPS backbone cannot take (a convention that does not grow crops, on a small person)."""


def check_metrics(metrics) -> tuple[str, ...]:
    metrics = tuple(metrics)
    bad = [m for m in metrics if m not in ALL_METRICS]
    if bad or not metrics:
        raise ValueError(f"unknown metric(s) {bad}; choose from {ALL_METRICS}")
    return metrics


def _check_layer(owner: str, name: str, arr, hw: tuple[int, int] | None) -> None:
    if arr is None:
        return
    if not isinstance(arr, np.ndarray) or not (arr.dtype == np.uint8 or np.issubdtype(arr.dtype, np.floating)):
        raise ValueError(f"{owner}.{name} must be a float or uint8 numpy array, got "
                         f"{type(arr).__name__} {getattr(arr, 'dtype', '')}")
    if arr.ndim != 3 or arr.shape[2] != 3 or (hw is not None and arr.shape[:2] != hw):
        want = f"{hw[0]}x{hw[1]}x3" if hw is not None else "(H, W, 3)"
        raise ValueError(f"{owner}.{name} must be {want}, got shape {arr.shape}")


@dataclass(frozen=True, eq=False)
class FramePrediction:
    """A method's layers for one frame, (H, W, 3) each, as its files store them (`dataset_io.decode_layer`):
    `image` float linear radiance (an EXR: brought to display space with the ground truth's exposure) or uint8
    display-space sRGB (a PNG); `albedo` float linear or uint8 sRGB; `normal` float vectors or uint8
    (2 v / 255 - 1). A layer that is None is not compared."""

    image: np.ndarray | None
    albedo: np.ndarray | None = None
    normal: np.ndarray | None = None

    def __post_init__(self) -> None:
        hw = None
        for name in ("image", "albedo", "normal"):
            arr = getattr(self, name)
            _check_layer("FramePrediction", name, arr, hw)
            if arr is not None and hw is None:
                hw = arr.shape[:2]


@dataclass(frozen=True, eq=False)
class FrameGroundTruth:
    """The dataset's frame: `mask` the (H, W) uint8 coverage (`_mask.png`), `exposure` the frame JSON's, `image` the
    linear radiance (`_image.exr`), `albedo` linear (`_albedo.exr`), `normal` vectors (`_normal.exr`). A layer the
    prediction has must be here too; the others may be None."""

    mask: np.ndarray
    exposure: float
    image: np.ndarray | None = None
    albedo: np.ndarray | None = None
    normal: np.ndarray | None = None

    def __post_init__(self) -> None:
        m = self.mask
        if not isinstance(m, np.ndarray) or m.dtype != np.uint8 or m.ndim != 2:
            raise ValueError(f"FrameGroundTruth.mask must be an (H, W) uint8 coverage (quantise a float mask with "
                             f"rh_common.colourspace.quantize8), got {type(m).__name__} {getattr(m, 'dtype', '')} "
                             f"{getattr(m, 'shape', '')}")
        if isinstance(self.exposure, bool) or not (isinstance(self.exposure, (int, float, np.floating))
                                                   and math.isfinite(self.exposure) and self.exposure > 0):
            raise ValueError(f"FrameGroundTruth.exposure must be a positive finite number, got {self.exposure!r}")
        for name in ("image", "albedo", "normal"):
            _check_layer("FrameGroundTruth", name, getattr(self, name), m.shape)

    def need(self, name: str) -> np.ndarray:
        arr = getattr(self, name)
        if arr is None:
            raise ValueError(f"the prediction has the {name} layer but FrameGroundTruth.{name} is None")
        return arr


def match_ground_truth(pred: FramePrediction, gt: FrameGroundTruth, conv: Convention) -> FrameGroundTruth:
    """`gt` at the prediction's size where the convention resamples (`resampling="area"`), else `gt` itself."""
    hw = next((getattr(pred, n).shape[:2] for n in ("image", "albedo", "normal") if getattr(pred, n) is not None),
              None)
    if hw is not None and hw != gt.mask.shape and conv.resampling == "area":
        return resample_ground_truth(gt, hw)
    return gt


def resample_ground_truth(gt: FrameGroundTruth, hw: tuple[int, int]) -> FrameGroundTruth:
    """The ground truth at the prediction's smaller size `hw`, as RelightableAvatar's loader makes it
    (`resampling="area"`, docs/EVALUATION.md): the display-space image and the albedo and normals area-averaged
    (OpenCV INTER_AREA), the mask by nearest neighbour (INTER_NEAREST). The image is averaged in display space, as
    their loader averages the 8-bit image's values, and kept as the linear radiance whose display value is that
    average, so everything downstream reads it as any ground truth."""
    hw = tuple(int(v) for v in hw)
    if gt.mask.shape == hw:
        return gt
    H, W = gt.mask.shape
    if not (0 < hw[0] <= H and 0 < hw[1] <= W):
        raise ValueError(f"area resampling shrinks the ground truth: {W}x{H} cannot become {hw[1]}x{hw[0]}")
    image = None
    if gt.image is not None:
        disp = shrink_area(np.asarray(display_from_stored(gt.image, gt), np.float64), hw)
        image = (srgb_decode(np.clip(disp, 0.0, 1.0)) / gt.exposure).astype(np.float32)
    albedo = None if gt.albedo is None else shrink_area(gt.albedo, hw).astype(np.float32)
    normal = None if gt.normal is None else shrink_area(gt.normal, hw).astype(np.float32)
    return FrameGroundTruth(mask=shrink_nearest(gt.mask, hw), exposure=gt.exposure, image=image, albedo=albedo,
                            normal=normal)


@dataclass
class LayerScores:
    """One compared layer's image metrics; None: not asked for, or undefined (empty ground-truth mask)."""

    lpips: float | None = None
    dists: float | None = None
    ssim: float | None = None
    psnr: float | None = None
    flip: float | None = None


@dataclass
class FrameScores:
    """Everything rh-eval reports for one frame. `compared` lists the layers that were compared (image, albedo,
    albedo_aligned, normal); a layer not compared has no scores (None) and no columns."""

    metrics: tuple[str, ...]
    empty_mask: bool
    compared: tuple[str, ...] = ()
    image: LayerScores | None = None
    image_aligned: LayerScores | None = None
    albedo: LayerScores | None = None
    albedo_aligned: LayerScores | None = None
    albedo_scale: list[float] | None = None
    """The per-channel scales of the aligned albedo (Convention.align_albedo)."""
    image_scale: list[float] | None = None
    """The per-channel scales of the aligned image (Convention.align_image)."""
    normal_deg: float | None = None

    def columns(self) -> dict:
        """The frame's cells of rh-eval's CSV: empty_mask, `<layer>_<metric>`, normal_deg, albedo_scale."""
        row: dict = {"empty_mask": self.empty_mask}
        for layer in LAYERS:
            scores = getattr(self, layer)
            if scores is not None:
                row.update({f"{layer}_{m}": getattr(scores, m) for m in IMAGE_METRICS if m in self.metrics})
        if self.albedo_scale is not None:
            row["albedo_scale"] = self.albedo_scale
        if self.image_scale is not None:
            row["image_scale"] = self.image_scale
        if "normal" in self.compared:
            row["normal_deg"] = self.normal_deg
        return row


@dataclass(frozen=True, eq=False)
class NetworkPair:
    """One layer's LPIPS/DISTS inputs: the (h, w, 3) float32 crops in [0, 1] the networks see, and the region."""

    layer: str  # image | image_aligned | albedo | albedo_aligned: where the scores go
    pred: np.ndarray
    target: np.ndarray
    region: Region

    @property
    def source(self) -> str:
        """The ground-truth layer compared against (an aligned layer is compared with the layer)."""
        return self.layer.removesuffix("_aligned")

    @property
    def shape(self) -> tuple[int, int]:
        return self.pred.shape[:2]


def _defined(v: float) -> float | None:
    """NaN (undefined: nothing inside the mask) as None, the way rh-eval stores it; +inf PSNR stays."""
    return None if math.isnan(v) else float(v)


def _score_layer(pairs: list[NetworkPair], layer: str, pred_crop: np.ndarray, gt_crop: np.ndarray, region: Region,
                 conv: Convention, metrics: tuple[str, ...]) -> LayerScores:
    """The CPU metrics of one cropped pair; its network inputs appended to `pairs`."""
    scores = LayerScores()
    if region.empty:
        return scores
    cpu = any(m in metrics for m in _CPU_METRICS)
    net = any(m in metrics for m in NETWORK_METRICS)
    p = g = None
    if cpu or (net and region.alpha is not None):
        p = composite(pred_crop, region, conv, "pred")
        g = composite(gt_crop, region, conv, "gt")
    mm = region.metric_mask
    if "psnr" in metrics:
        scores.psnr = _defined(psnr(p, g, data_range=1.0, mask=mm if region.psnr_mask is None else region.psnr_mask))
    if "ssim" in metrics:
        scores.ssim = _defined(ssim(p, g, data_range=conv.ssim_data_range, mask=mm, window=conv.ssim_window))
    if "flip" in metrics:
        scores.flip = _defined(flip(p, g, data_range=1.0, mask=mm, ppd=conv.flip_ppd))
    if net:
        need = LPIPS_MIN_SIDE[conv.backbone]
        if "lpips" in metrics and min(region.shape) < need:
            raise CropTooSmallError(
                f"the {layer} region is {region.shape[1]}x{region.shape[0]} px, smaller than the {need} px LPIPS-"
                f"{conv.backbone} needs (convention {conv.name!r} uses min_crop {conv.min_crop}); evaluate at a "
                f"higher resolution or leave lpips out of --metrics")
        if p is None:  # nothing to composite: the crop itself, the same float32 values as via float64
            p, g = pred_crop, gt_crop
        # float32, the networks' input type: half the memory while rh-eval queues pairs for a batch
        pairs.append(NetworkPair(layer, np.asarray(p, dtype=np.float32), np.asarray(g, dtype=np.float32), region))
    return scores


def prepare_frame(pred: FramePrediction, gt: FrameGroundTruth, convention: Convention | None = None,
                  metrics=ALL_METRICS) -> tuple[FrameScores, list[NetworkPair]]:
    """Everything about one frame except LPIPS and DISTS: the scores so far and the networks' inputs."""
    conv = convention or Convention()
    metrics = check_metrics(metrics)
    gt = match_ground_truth(pred, gt, conv)
    for name in ("image", "albedo", "normal"):
        arr = getattr(pred, name)
        if arr is not None and arr.shape[:2] != gt.mask.shape:
            raise ValueError(f"FramePrediction.{name} is {arr.shape[1]}x{arr.shape[0]}, the ground truth "
                             f"{gt.mask.shape[1]}x{gt.mask.shape[0]}")
    region = compute_region(gt.mask, conv)
    crop = (slice(region.y0, region.y1), slice(region.x0, region.x1))
    inside = gt.mask >= conv.mask_threshold
    scores = FrameScores(metrics, empty_mask=not inside.any())
    pairs: list[NetworkPair] = []
    compared = []
    image_metrics = any(m in metrics for m in IMAGE_METRICS)
    if image_metrics and pred.image is not None:
        # per-pixel conversions: only the evaluated region is brought to display space (`gt` gives the exposure)
        p_img = display_from_stored(pred.image[crop], gt)
        g_img = display_from_stored(gt.need("image")[crop], gt)
        scores.image = _score_layer(pairs, "image", p_img, g_img, region, conv, metrics)
        compared.append("image")
        if conv.align_image != "none":
            # the region holds the whole mask, so the scales over the crop are the scales over the frame
            aligned, scales = align_albedo(p_img, g_img, inside[crop], conv.align_image)
            scores.image_scale = scales
            scores.image_aligned = _score_layer(pairs, "image_aligned", aligned, g_img, region, conv, metrics)
            compared.append("image_aligned")
    if image_metrics and pred.albedo is not None:
        a_region = compute_region(gt.mask, conv, "albedo") if conv.albedo_region != "same" else region
        a_crop = (slice(a_region.y0, a_region.y1), slice(a_region.x0, a_region.x1))
        gt_lin = gt_albedo_values(albedo_from_stored(gt.need("albedo")), conv)
        pr_lin = albedo_from_stored(pred.albedo)
        g_sp = albedo_to_space(gt_lin[a_crop], conv)
        scores.albedo = _score_layer(pairs, "albedo", albedo_to_space(pr_lin[a_crop], conv), g_sp, a_region, conv,
                                     metrics)
        compared.append("albedo")
        if conv.align_albedo != "none":
            aligned, scales = align_albedo(pr_lin, gt_lin, inside, conv.align_albedo)  # scales from the whole mask
            scores.albedo_scale = scales
            scores.albedo_aligned = _score_layer(pairs, "albedo_aligned", albedo_to_space(aligned[a_crop], conv),
                                                 g_sp, a_region, conv, metrics)
            compared.append("albedo_aligned")
    if "normal" in metrics and pred.normal is not None:
        p_n = normal_from_stored(pred.normal)
        n_mask = inside if conv.normal_mask == "gt" else inside & np.any(p_n != 0, axis=-1)
        scores.normal_deg = _defined(normal_angular_error(p_n, normal_from_stored(gt.need("normal")), mask=n_mask))
        compared.append("normal")
    scores.compared = tuple(compared)
    return scores, pairs


FeatureSource = Callable[[str, list[NetworkPair], Callable[[], list]], list]


def score_pairs(pairs: list[NetworkPair], convention: Convention | None = None, metrics=ALL_METRICS, *,
                reference: FeatureSource | None = None) -> dict[str, np.ndarray]:
    """LPIPS and DISTS of pairs of one shape, run as one batch: {metric: (N,) float64} for each network metric in
    `metrics`. `reference(metric, pairs, compute)` may supply the targets' features (rh-eval: from its cache;
    `compute()` runs `lpips_features`/`dists_features` on the pairs' targets); default: computed here."""
    conv = convention or Convention()
    out: dict[str, np.ndarray] = {}
    if not pairs:
        return out
    preds = [p.pred for p in pairs]
    for metric in NETWORK_METRICS:
        if metric not in metrics:
            continue
        fn, features = (lpips, lpips_features) if metric == "lpips" else (dists, dists_features)
        kw = {"backbone": conv.backbone, "normalize": conv.lpips_normalize} if metric == "lpips" else {}

        def compute(features=features, kw=kw):
            return features([p.target for p in pairs], data_range=1.0, **kw)

        feats = compute() if reference is None else reference(metric, pairs, compute)
        out[metric] = fn(preds, target_features=feats, data_range=1.0, **kw)
    return out


def record_pair_scores(scores: FrameScores, pair: NetworkPair, values: dict[str, float]) -> None:
    """Write one pair's network scores (from `score_pairs`) into its frame's scores."""
    layer = getattr(scores, pair.layer)
    for metric, v in values.items():
        setattr(layer, metric, float(v))


def score_frame(pred: FramePrediction, gt: FrameGroundTruth, convention: Convention | None = None,
                metrics=ALL_METRICS) -> FrameScores:
    """One frame's scores as rh-eval computes them (see the module docstring): `prepare_frame`, then LPIPS and DISTS
    of the frame's pairs (one batch per crop shape)."""
    conv = convention or Convention()
    scores, pairs = prepare_frame(pred, gt, conv, metrics)
    groups: dict[tuple[int, int], list[NetworkPair]] = {}
    for p in pairs:
        groups.setdefault(p.shape, []).append(p)
    for group in groups.values():
        values = score_pairs(group, conv, scores.metrics)
        for i, p in enumerate(group):
            record_pair_scores(scores, p, {m: v[i] for m, v in values.items()})
    return scores


def read_frame(frame: PredFrame, metrics=ALL_METRICS, *, layers=("image", "albedo", "normal"),
               stored: dict[Path, np.ndarray] | None = None, smaller_ok: bool = False) -> tuple[FramePrediction, FrameGroundTruth]:
    """One frame of a predictions folder (`dataset_io.scan_predictions`) and its ground truth, as `score_frame` takes
    them; only the prediction's `layers` that `metrics` compare are read. `stored`: prediction layers already
    decoded, by path (taken out of it; rh-eval's up-front check keeps them)."""
    metrics = check_metrics(metrics)
    bad = [name for name in layers if name not in ("image", "albedo", "normal")]
    if bad:
        raise ValueError(f"unknown layer(s) {bad}; choose from ('image', 'albedo', 'normal')")
    stored = stored if stored is not None else {}
    gt = frame.gt

    def pred_layer(path: Path | None) -> np.ndarray | None:
        if path is None:
            return None
        arr = stored.pop(path, None)
        return arr if arr is not None else decode_layer(path, gt, smaller_ok)

    image_metrics = any(m in metrics for m in IMAGE_METRICS)
    image = image_metrics and "image" in layers
    albedo = image_metrics and "albedo" in layers and frame.albedo is not None
    normals = "normal" in metrics and "normal" in layers and frame.normal is not None
    prediction = FramePrediction(image=pred_layer(frame.image) if image else None,
                                 albedo=pred_layer(frame.albedo) if albedo else None,
                                 normal=pred_layer(frame.normal) if normals else None)
    truth = FrameGroundTruth(mask=read_gt_mask(gt), exposure=gt.exposure,
                             image=read_gt_image_stored(gt) if image else None,
                             albedo=read_gt_albedo(gt) if albedo else None,
                             normal=read_gt_normal(gt) if normals else None)
    return prediction, truth
