"""The evaluation engine behind `rh-eval`: frames -> regions -> metrics -> per-frame rows -> summaries.

Speed: the networks are loaded once per process (`Evaluator` keeps them); the evaluated region is cropped before
they run; crops of equal shape are batched (`batch_size`); ground-truth features are computed once and kept in a
cache keyed by the ground-truth files' sha256, the convention and the network (in memory, bounded, plus an optional
on-disk folder), so evaluating a second method against the same dataset skips every ground-truth forward pass.
"""
from __future__ import annotations

import hashlib
import math
import os
import sys
from collections import OrderedDict, deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from rh_common import layout
from rh_common.imageio import ImageFileError, sha256_file

from . import __version__
from .conventions import Convention, align_albedo, albedo_to_space, composite, compute_region
from .dataset_io import (DatasetIndex, PredictionError, PredictionIndex, albedo_from_stored, check_header,
                         decode_layer, display_from_stored, load_dataset, normal_from_stored, read_gt_albedo,
                         read_gt_image_stored, read_gt_mask, read_gt_normal, scan_predictions)
from .metrics import flip, normal_angular_error, psnr, ssim
from .metrics.dists import get_dists_net
from .metrics.lpips import get_lpips_net
from .weights import WEIGHTS, weights_record

__all__ = ["ALL_METRICS", "EvalOptions", "Evaluator", "FeatureCache", "summarise", "metric_columns",
           "RESULT_FORMAT"]

RESULT_FORMAT = "rh-eval/1"
ALL_METRICS = ("lpips", "dists", "ssim", "psnr", "flip", "normal")
_IMAGE_METRICS = ("lpips", "dists", "ssim", "psnr", "flip")
_NETWORK_METRICS = ("lpips", "dists")


@dataclass
class EvalOptions:
    convention: Convention = field(default_factory=Convention)
    metrics: tuple[str, ...] = ALL_METRICS
    batch_size: int = 4
    cache_dir: Path | None = None
    cache_mb: int = 2048
    allow_incomplete: bool = False
    progress: bool | None = None  # None: only on a terminal
    threads: int | None = None
    workers: int | None = None
    """Threads that decode files and compute the CPU metrics beside the networks (None: torch's thread count)."""
    prefetch: int | None = None
    """Frames prepared ahead of the networks (None: two batches)."""
    overlap: bool | None = None
    """Prepare frames while the networks run (True) or in turns with them (False). None: overlap only when there
    are cores for both the torch threads and the workers; on fewer, torch's threads, which wait for each other at
    every operation, lose more to a busy core than overlapping gains (measured: docs/EVALUATION.md, Speed)."""
    preload_mb: int = 1024
    """Prediction pixels decoded by the up-front check are kept (up to this many MB) instead of decoded again."""

    def __post_init__(self) -> None:
        bad = [m for m in self.metrics if m not in ALL_METRICS]
        if bad or not self.metrics:
            raise ValueError(f"unknown metric(s) {bad}; choose from {ALL_METRICS}")
        if self.batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {self.batch_size}")
        for name in ("workers", "prefetch", "threads"):
            v = getattr(self, name)
            if v is not None and v < 1:
                raise ValueError(f"{name} must be >= 1, got {v}")
        if self.preload_mb < 0:
            raise ValueError(f"preload_mb must be >= 0, got {self.preload_mb}")


def metric_columns(metrics, *, albedo: bool, aligned: bool, normal: bool) -> list[str]:
    cols = [f"image_{m}" for m in _IMAGE_METRICS if m in metrics]
    if normal and "normal" in metrics:
        cols.append("normal_deg")
    if albedo:
        cols += [f"albedo_{m}" for m in _IMAGE_METRICS if m in metrics]
        if aligned:
            cols += [f"albedo_aligned_{m}" for m in _IMAGE_METRICS if m in metrics]
    return cols


# --------------------------------------------------------------------------------------------- feature cache
class FeatureCache:
    """Ground-truth network features: an in-memory LRU bounded in bytes, optionally backed by a folder of `.pt`
    files (read back with `torch.load(weights_only=True)`). Keys are hex digests of (GT file sha256s, convention,
    network, weight sha256)."""

    def __init__(self, max_bytes: int = 2 << 30, cache_dir: Path | None = None) -> None:
        self.max_bytes = max_bytes
        self.cache_dir = Path(cache_dir) if cache_dir else None
        self._mem: OrderedDict[str, tuple[Any, int]] = OrderedDict()
        self._bytes = 0
        self.hits = self.misses = self.disk_hits = 0

    @staticmethod
    def _nbytes(obj) -> int:
        if isinstance(obj, torch.Tensor):
            return obj.numel() * obj.element_size()
        if isinstance(obj, (list, tuple)):
            return sum(FeatureCache._nbytes(o) for o in obj)
        return 0

    def get(self, key: str):
        if key in self._mem:
            self._mem.move_to_end(key)
            self.hits += 1
            return self._mem[key][0]
        if self.cache_dir is not None:
            path = self.cache_dir / f"{key}.pt"
            if path.is_file():
                try:
                    obj = torch.load(path, map_location="cpu", weights_only=True)
                except Exception as exc:  # a damaged cache entry is recomputed, and said so
                    print(f"rh-eval: ignoring unreadable cache entry {path} ({exc})", file=sys.stderr)
                else:
                    self.disk_hits += 1
                    self._remember(key, obj)
                    return obj
        self.misses += 1
        return None

    def put(self, key: str, obj) -> None:
        self._remember(key, obj)
        if self.cache_dir is not None:
            from rh_common.imageio import atomic_path

            self.cache_dir.mkdir(parents=True, exist_ok=True)
            with atomic_path(self.cache_dir / f"{key}.pt") as tmp:
                torch.save(_clone(obj), tmp)  # a view would save its whole batch

    def _remember(self, key: str, obj) -> None:
        n = self._nbytes(obj)
        if n > self.max_bytes:
            return
        self._mem[key] = (obj, n)
        self._bytes += n
        while self._bytes > self.max_bytes:
            _, (_, m) = self._mem.popitem(last=False)
            self._bytes -= m


def _clone(obj):
    if isinstance(obj, torch.Tensor):
        return obj.clone()
    return type(obj)(_clone(o) for o in obj)


# --------------------------------------------------------------------------------------------- summaries
def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and not math.isnan(v)


def summarise(values: list, *, psnr_like: bool) -> dict:
    """Mean and population std (ddof=0) of the defined values of one metric.

    `None`/NaN values (undefined: empty mask) are counted in `n_undefined`, never averaged. PSNR: +inf values
    (identical images) are counted in `n_infinite` and left out of the mean and std, which are over the finite
    values; when every defined value is infinite, mean is the string "inf" and std is null.
    """
    defined = [float(v) for v in values if _is_num(v)]
    out: dict[str, Any] = {"n": len(defined), "n_undefined": len(values) - len(defined)}
    if psnr_like:
        finite = [v for v in defined if math.isfinite(v)]
        out["n_infinite"] = len(defined) - len(finite)
        if finite:
            out["mean"] = float(np.mean(finite))
            out["std"] = float(np.std(finite))
        elif defined:
            out["mean"], out["std"] = "inf", None
        else:
            out["mean"], out["std"] = None, None
        return out
    if defined:
        out["mean"] = float(np.mean(defined))
        out["std"] = float(np.std(defined))
    else:
        out["mean"], out["std"] = None, None
    return out


# --------------------------------------------------------------------------------------------- evaluator
@dataclass
class _NetItem:
    row: dict
    column_prefix: str  # image | albedo | albedo_aligned
    pred: np.ndarray  # (3, h, w) float32, the network's input layout
    gt: np.ndarray
    gt_key: str  # file-identity + convention part of the cache key

    @property
    def hw(self) -> tuple[int, int]:
        return self.pred.shape[1:]


def _chw32(img: np.ndarray) -> np.ndarray:
    """(h, w, 3) float64 in [0, 1] -> (3, h, w) contiguous float32, the networks' layout."""
    return np.ascontiguousarray(img.transpose(2, 0, 1), dtype=np.float32)


class Evaluator:
    """Holds the networks and the ground-truth feature cache; `evaluate` one predictions folder at a time."""

    def __init__(self, options: EvalOptions | None = None) -> None:
        self.options = options or EvalOptions()
        if self.options.threads:
            torch.set_num_threads(self.options.threads)
        conv = self.options.convention
        self.lpips_net = get_lpips_net(conv.backbone) if "lpips" in self.options.metrics else None
        self.dists_net = get_dists_net() if "dists" in self.options.metrics else None
        self.cache = FeatureCache(self.options.cache_mb << 20, self.options.cache_dir)
        self._hash_memo: dict[tuple[str, int, int], str] = {}
        self._queue: list[_NetItem] = []

    # ---------------------------------------------------------------- bookkeeping
    def weight_names(self) -> list[str]:
        names = []
        if self.lpips_net is not None:
            b = "alexnet" if self.options.convention.backbone == "alex" else "vgg16"
            names += [b, f"lpips_{self.options.convention.backbone}_v0.1"]
        if self.dists_net is not None:
            names += ["vgg16", "dists_alpha_beta"]
        return sorted(set(names))

    def _file_sha(self, path: Path) -> str:
        st = path.stat()
        k = (str(path), st.st_mtime_ns, st.st_size)
        if k not in self._hash_memo:
            self._hash_memo[k] = sha256_file(path)
        return self._hash_memo[k]

    def _net_key(self, gt_key: str, net: str) -> str:
        conv = self.options.convention
        if net == "lpips":
            wnames = ["alexnet" if conv.backbone == "alex" else "vgg16", f"lpips_{conv.backbone}_v0.1"]
        else:
            wnames = ["vgg16", "dists_alpha_beta"]
        ident = "|".join([gt_key, net, conv.backbone if net == "lpips" else "", __version__]
                         + [WEIGHTS[w].sha256 for w in wnames])
        return hashlib.sha256(ident.encode()).hexdigest()

    # ---------------------------------------------------------------- networks
    def _gt_features(self, net: str, items: list[_NetItem], batch: torch.Tensor):
        keys = [self._net_key(it.gt_key, net) for it in items]
        found: dict[str, Any] = {}
        for k in dict.fromkeys(keys):  # unique keys, in order
            found[k] = self.cache.get(k)
        first = {k: keys.index(k) for k in found}
        todo = [first[k] for k, v in found.items() if v is None]
        cached = [found[k] for k in keys]
        if todo:
            # The whole batch, not just the missing items: oneDNN picks its kernels by batch size (a crop's
            # features at N=1 differ from N=2 in the last bits), and ground truth run exactly like the
            # prediction makes a prediction equal to the ground truth score exactly 0.
            if net == "lpips":
                feats = self.lpips_net.features(batch)
                per = [[f[i:i + 1] for f in feats] for i in todo]
            else:
                prep = self.dists_net.prepare(self.dists_net.features(batch))
                per = [[(m[i:i + 1], c[i:i + 1], v[i:i + 1]) for (m, c, v) in prep] for i in todo]
            for j, i in enumerate(todo):
                self.cache.put(keys[i], per[j])
                found[keys[i]] = per[j]
            if len(todo) == len(items):  # in batch order: the batched tensors as they are
                return feats if net == "lpips" else prep
            cached = [found[k] for k in keys]
        # stack per-item features back into batched tensors
        n_taps = len(cached[0])
        if net == "lpips":
            return [torch.cat([c[t] for c in cached]) for t in range(n_taps)]
        return [tuple(torch.cat([c[t][q] for c in cached]) for q in range(3)) for t in range(n_taps)]

    def _flush(self) -> None:
        if not self._queue:
            return
        groups: dict[tuple[int, int], list[_NetItem]] = {}
        for it in self._queue:
            groups.setdefault(it.hw, []).append(it)
        self._queue = []
        bs = self.options.batch_size
        for items_all in groups.values():
            for s in range(0, len(items_all), bs):
                items = items_all[s:s + bs]
                xp = torch.from_numpy(np.stack([it.pred for it in items]))
                xg = torch.from_numpy(np.stack([it.gt for it in items]))
                if self.lpips_net is not None:
                    fg = self._gt_features("lpips", items, xg)
                    d = self.lpips_net.distance(self.lpips_net.features(xp), fg).numpy()
                    for it, v in zip(items, d):
                        it.row[f"{it.column_prefix}_lpips"] = float(v)
                if self.dists_net is not None:
                    fg = self._gt_features("dists", items, xg)
                    fp = self.dists_net.prepare(self.dists_net.features(xp))
                    d = self.dists_net.distance_prepared(fg, fp).numpy()  # official order: (reference, distorted)
                    for it, v in zip(items, d):
                        it.row[f"{it.column_prefix}_dists"] = float(v)

    # ---------------------------------------------------------------- per frame (worker threads)
    def _pair(self, row: dict, items: list, prefix: str, pred_crop: np.ndarray, gt_crop: np.ndarray, region,
              gt_key: str) -> None:
        """CPU metrics of one cropped pair into `row`; its network inputs appended to `items`."""
        conv = self.options.convention
        metrics = self.options.metrics
        if region.empty:
            for m in _IMAGE_METRICS:
                if m in metrics:
                    row[f"{prefix}_{m}"] = None
            return
        cpu = [m for m in ("psnr", "ssim", "flip") if m in metrics]
        net = any(m in metrics for m in _NETWORK_METRICS)
        p = g = None
        if cpu or (net and region.alpha is not None):
            p = composite(pred_crop, region, conv)
            g = composite(gt_crop, region, conv)
        mm = region.metric_mask
        if "psnr" in metrics:
            row[f"{prefix}_psnr"] = psnr(p, g, data_range=1.0, mask=mm)
        if "ssim" in metrics:
            row[f"{prefix}_ssim"] = ssim(p, g, data_range=1.0, mask=mm)
        if "flip" in metrics:
            row[f"{prefix}_flip"] = flip(p, g, data_range=1.0, mask=mm, ppd=conv.flip_ppd)
        if net:
            key = f"{gt_key}|{prefix.replace('_aligned', '')}|{conv.region_key()}|{region.y0},{region.y1},{region.x0},{region.x1}"
            if p is None:  # nothing to composite: float32 straight from the crop, the same values as via float64
                p, g = pred_crop, gt_crop
            items.append(_NetItem(row, prefix, _chw32(p), _chw32(g), key))

    def _flush_full_groups(self) -> None:
        """Run every shape group that has a full batch; keep the rest queued."""
        counts: dict[tuple[int, int], int] = {}
        for it in self._queue:
            counts[it.hw] = counts.get(it.hw, 0) + 1
        ready = {s for s, n in counts.items() if n >= self.options.batch_size}
        if len(self._queue) > 8 * self.options.batch_size:  # many odd shapes: bound the memory
            ready = set(counts)
        if not ready:
            return
        keep = [it for it in self._queue if it.hw not in ready]
        self._queue = [it for it in self._queue if it.hw in ready]
        self._flush()
        self._queue = keep

    def _prepare(self, pf, pred: PredictionIndex, stored: dict) -> tuple[dict, list]:
        """Everything about one frame except the networks: read, crop, convert, CPU metrics. Runs in a worker
        thread; returns the frame's row and its network inputs."""
        conv = self.options.convention
        metrics = self.options.metrics
        gt = pf.gt

        def pred_layer(path: Path) -> np.ndarray:
            arr = stored.pop(path, None)
            return arr if arr is not None else decode_layer(path, gt)

        row: dict[str, Any] = {"subject": gt.subject, "frame": gt.index}
        items: list[_NetItem] = []
        mask = read_gt_mask(gt)
        region = compute_region(mask, conv)
        crop = (slice(region.y0, region.y1), slice(region.x0, region.x1))
        inside = mask >= conv.mask_threshold
        row["empty_mask"] = not inside.any()
        frame_id = "|".join([self._file_sha(gt.json_path), self._file_sha(gt.layer("mask.png"))])
        image_metrics = any(m in metrics for m in _IMAGE_METRICS)
        if image_metrics:
            pr = pred_layer(pf.image)
            gt_img = read_gt_image_stored(gt)
            # per-pixel conversions: only the evaluated region is brought to display space
            self._pair(row, items, "image", display_from_stored(pr[crop], gt), display_from_stored(gt_img[crop], gt),
                       region, frame_id + "|" + self._file_sha(gt.layer("image.exr")))
        if pred.has_albedo and pf.albedo is not None and image_metrics:
            gt_lin = read_gt_albedo(gt)
            pr_lin = albedo_from_stored(pred_layer(pf.albedo))
            akey = frame_id + "|" + self._file_sha(gt.layer("albedo.exr"))
            g_sp = albedo_to_space(gt_lin[crop], conv)
            self._pair(row, items, "albedo", albedo_to_space(pr_lin[crop], conv), g_sp, region, akey)
            if conv.align_albedo:
                aligned, scales = align_albedo(pr_lin, gt_lin, inside)  # scales from the whole mask
                row["albedo_scale"] = scales
                self._pair(row, items, "albedo_aligned", albedo_to_space(aligned[crop], conv), g_sp, region, akey)
        if pred.has_normal and pf.normal is not None and "normal" in metrics:
            row["normal_deg"] = normal_angular_error(normal_from_stored(pred_layer(pf.normal)), read_gt_normal(gt),
                                                     mask=inside)
        return row, items

    def _workers(self) -> int:
        return self.options.workers or max(1, torch.get_num_threads())

    def check_predictions(self, pred: PredictionIndex) -> dict:
        """Check the whole prediction set before anything is computed, listing every bad file: headers first
        (resolution, channel count, bit depth, format) for every file, then every file decoded in full (corrupt
        data, NaN/Inf) on the worker threads. Returns decoded pixels to reuse, up to `preload_mb`."""
        metrics = self.options.metrics
        image_metrics = any(m in metrics for m in _IMAGE_METRICS)
        problems: list[str] = []
        files = []
        for pf in pred.frames:
            needed = ["mask.png"]
            if image_metrics:
                needed.append("image.exr")
                if pf.albedo is not None:
                    needed.append("albedo.exr")
            if pf.normal is not None and "normal" in metrics:
                needed.append("normal.exr")
            for name in needed:
                if not pf.gt.layer(name).is_file():
                    problems.append(f"{pf.gt.layer(name)}: ground-truth file missing (the dataset is incomplete: "
                                    f"regenerate or re-copy it)")
            used = [pf.image if image_metrics else None, pf.albedo if image_metrics else None,
                    pf.normal if "normal" in metrics else None]
            for path in used:
                if path is None:
                    continue
                try:
                    check_header(path, pf.gt)
                except ImageFileError as exc:
                    problems.append(str(exc))
                else:
                    files.append((path, pf.gt))
        stored: dict[Path, np.ndarray] = {}
        budget, used_bytes = self.options.preload_mb << 20, 0

        def decode(item):
            try:
                return decode_layer(*item)
            except ImageFileError as exc:
                return exc

        with ThreadPoolExecutor(self._workers()) as pool:
            for (path, _), arr in zip(files, pool.map(decode, files)):
                if isinstance(arr, Exception):
                    problems.append(str(arr))
                elif used_bytes + arr.nbytes <= budget and not problems:
                    stored[path] = arr
                    used_bytes += arr.nbytes
        if problems:
            raise PredictionError(pred.root, problems)
        return stored

    # ---------------------------------------------------------------- public
    def evaluate(self, pred_root: str | Path, dataset: DatasetIndex | str | Path, protocol: str = "a",
                 on_frame: Callable[[int, int], None] | None = None) -> tuple[dict, list[dict], list[str]]:
        """Evaluate one predictions folder. Returns (result JSON dict, per-frame rows, CSV columns).

        Every prediction file is checked (`check_predictions`) before any metric is computed; nothing is
        returned (or written by the CLI) unless every frame was evaluated."""
        ds = dataset if isinstance(dataset, DatasetIndex) else load_dataset(dataset, protocol)
        pred = scan_predictions(pred_root, ds, allow_incomplete=self.options.allow_incomplete)
        stored = self.check_predictions(pred)
        self._cache_start = {k: getattr(self.cache, k) for k in ("hits", "disk_hits", "misses")}
        opts = self.options
        conv = opts.convention
        rows: list[dict] = []
        progress = opts.progress if opts.progress is not None else sys.stderr.isatty()
        bar = None
        if progress and len(pred.frames) > 1:
            from tqdm import tqdm
            bar = tqdm(total=len(pred.frames), desc=f"rh-eval {pred.method.get('name', '')}", unit="frame",
                       file=sys.stderr)
        overlap = opts.overlap if opts.overlap is not None else \
            (os.cpu_count() or 1) >= torch.get_num_threads() + self._workers()
        ahead = opts.prefetch or (2 * opts.batch_size if overlap else opts.batch_size)
        pool = ThreadPoolExecutor(self._workers())
        try:
            # frames are prepared on the workers, in order, a bounded number ahead of the networks (memory)
            todo = iter(pred.frames)
            pending = deque(pool.submit(self._prepare, pf, pred, stored) for pf in islice(todo, ahead))
            while pending:
                row, items = pending.popleft().result()
                if overlap:
                    pending.extend(pool.submit(self._prepare, pf, pred, stored) for pf in islice(todo, 1))
                rows.append(row)
                self._queue.extend(items)
                if len(self._queue) >= opts.batch_size:
                    self._flush_full_groups()
                if not overlap and not pending:
                    pending.extend(pool.submit(self._prepare, pf, pred, stored) for pf in islice(todo, ahead))
                if bar is not None:
                    bar.update(1)
                if on_frame is not None:
                    on_frame(len(rows), len(pred.frames))
            self._flush()
        except BaseException:
            self._queue = []
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            if bar is not None:
                bar.close()
        cols = metric_columns(opts.metrics, albedo=pred.has_albedo, aligned=conv.align_albedo,
                              normal=pred.has_normal)
        for r in rows:
            for c in cols:
                v = r.get(c)
                if isinstance(v, float) and math.isnan(v):
                    r[c] = None  # undefined (empty mask): stored as null, counted, never averaged
                else:
                    r.setdefault(c, None)
        result = self._result(ds, pred, rows, cols)
        return result, rows, cols

    def _result(self, ds: DatasetIndex, pred: PredictionIndex, rows: list[dict], cols: list[str]) -> dict:
        import flip_evaluator  # noqa: F401  (version only)
        import skimage
        from importlib.metadata import version

        def block(rs):
            return {c: summarise([r.get(c) for r in rs], psnr_like=c.endswith("_psnr")) for c in cols}

        per_subject = {}
        for s in ds.subjects:
            rs = [r for r in rows if r["subject"] == s]
            if rs:
                per_subject[s] = {"n_frames": len(rs), "metrics": block(rs)}
        complete = not pred.missing
        kind = str(pred.method.get("kind", "method"))
        return {
            "format": RESULT_FORMAT,
            "method": pred.method,
            "kind": kind,
            "complete": complete,
            "missing": pred.missing,
            "predictions": str(pred.root),
            "dataset": {"root": str(ds.root), "protocol": ds.protocol, "split": "test",
                        "manifest_sha256": ds.manifest_sha256, "n_frames": len(ds.frames),
                        "content_identity": layout.split_identity(ds.root, ds.protocol, layout.TEST_SPLIT),
                        "subjects": ds.subjects},
            "n_frames_evaluated": len(rows),
            "n_frames_empty_mask": sum(1 for r in rows if r.get("empty_mask")),
            "layers": {"image": True, "albedo": pred.has_albedo, "normal": pred.has_normal},
            "convention": self.options.convention.to_json(),
            "metrics": list(self.options.metrics),
            "columns": cols,
            "overall": block(rows),
            "per_subject": per_subject,
            "rules": {
                "psnr_infinite": "identical images give PSNR +inf: per-frame CSV writes 'inf'; means and stds are "
                                 "over finite frames, n_infinite counts the others; mean is the string 'inf' if "
                                 "every frame is infinite",
                "undefined": "null = undefined (empty ground-truth mask), counted in n_undefined, never averaged",
                "std": "population standard deviation (ddof=0) over frames",
            },
            "versions": {
                "rh_eval": __version__,
                "torch": torch.__version__,
                "numpy": np.__version__,
                "scikit-image": skimage.__version__,
                "flip-evaluator": version("flip-evaluator"),
                "lpips": "v0.1 linear heads (official), net=" + self.options.convention.backbone,
                "dists": "DISTS_pytorch forward, VGG16 + L2 pooling",
                "ssim": "Wang et al. 2004 via skimage.metrics.structural_similarity (gaussian, sigma 1.5)",
            },
            "weights": weights_record(self.weight_names()),
            "flip_ppd": self.options.convention.flip_ppd,
            "gt_feature_cache": {k: getattr(self.cache, k) - self._cache_start.get(k, 0)
                                 for k in ("hits", "disk_hits", "misses")},
            "python": sys.version.split()[0],
        }
