"""The evaluation engine behind `rh-eval`: a predictions folder and a dataset -> per-frame rows -> the result JSON.

In: `EvalOptions` (convention, metrics, batching, cache, threads), a predictions folder, a dataset, a protocol and
    the scored split (`test` unless told another, e.g. `olat`).
Out: `Evaluator.evaluate` -> (result JSON dict, per-frame rows, CSV columns), and `Evaluator.thumbnails` (the
     tiles of the seeded frame selection, `rh_eval.thumbnails`); `rh_eval.report` writes them.

Each frame is scored by `rh_eval.scoring` (the same code as the public `score_frame`): `prepare_frame` on worker
threads, then LPIPS/DISTS through `score_pairs` on batches of equal-shape crops from many frames (`batch_size`).
Speed: the networks are loaded once per process; the evaluated region is cropped before they run; ground-truth
features are computed once and kept in a cache keyed by the ground-truth files' sha256, the convention and the
network (in memory, bounded, plus an optional on-disk folder), so evaluating a second method against the same dataset
skips every ground-truth forward pass.
"""
from __future__ import annotations

import hashlib
import os
import sys
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from rh_common import layout
from rh_common.imageio import ImageFileError, sha256_file
from rh_common.weights import WEIGHTS, weights_record

from . import __version__
from .conventions import Convention
from .dataset_io import (DatasetIndex, PredictionError, PredictionIndex, check_header, decode_layer, load_dataset,
                         scan_predictions)
from .feature_cache import FeatureCache
from .metrics.dists import get_dists_net
from .metrics.lpips import get_lpips_net
from .report import summarise
from .scoring import (ALL_METRICS, IMAGE_METRICS, CropTooSmallError, FrameScores, NetworkPair, check_metrics,
                      prepare_frame, read_frame, record_pair_scores, score_pairs)
from .thumbnails import ThumbnailSet, collect_thumbnails, frame_tiles, select_fixed

__all__ = ["ALL_METRICS", "EvalOptions", "Evaluator", "FeatureCache", "summarise", "metric_columns",
           "RESULT_FORMAT"]

RESULT_FORMAT = "rh-eval/1"


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
    thumbnails: bool = False
    """Keep display-space tiles of the seeded frame selection (`rh_eval.thumbnails`) in `Evaluator.thumbnails`
    (rh-eval's default; off here, so that code timing or scoring through the API pays for no pictures)."""

    def __post_init__(self) -> None:
        check_metrics(self.metrics)
        if self.batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {self.batch_size}")
        for name in ("workers", "prefetch", "threads"):
            v = getattr(self, name)
            if v is not None and v < 1:
                raise ValueError(f"{name} must be >= 1, got {v}")
        if self.preload_mb < 0:
            raise ValueError(f"preload_mb must be >= 0, got {self.preload_mb}")


def metric_columns(metrics, *, albedo: bool, aligned: bool, normal: bool, image_aligned: bool = False) -> list[str]:
    cols = [f"image_{m}" for m in IMAGE_METRICS if m in metrics]
    if image_aligned:
        cols += [f"image_aligned_{m}" for m in IMAGE_METRICS if m in metrics]
    if normal and "normal" in metrics:
        cols.append("normal_deg")
    if albedo:
        cols += [f"albedo_{m}" for m in IMAGE_METRICS if m in metrics]
        if aligned:
            cols += [f"albedo_aligned_{m}" for m in IMAGE_METRICS if m in metrics]
    return cols


# --------------------------------------------------------------------------------------------- evaluator
@dataclass
class _NetItem:
    scores: FrameScores  # the frame whose scores the pair's LPIPS/DISTS go into
    pair: NetworkPair
    gt_key: str  # file identity + layer + convention + region: the ground-truth cache key before the network


def _take(obj, i: int):
    """Item `i` of a batch-first feature structure (tensors in lists and tuples), keeping the batch dimension."""
    if isinstance(obj, torch.Tensor):
        return obj[i:i + 1]
    return type(obj)(_take(o, i) for o in obj)


def _cat(objs: list):
    """The inverse of `_take` over a list of items: their features as one batch."""
    if isinstance(objs[0], torch.Tensor):
        return torch.cat(objs)
    return type(objs[0])(_cat([o[t] for o in objs]) for t in range(len(objs[0])))


class Evaluator:
    """Holds the ground-truth feature cache; `evaluate` one predictions folder at a time."""

    def __init__(self, options: EvalOptions | None = None) -> None:
        self.options = options or EvalOptions()
        # Loaded (once per process) and checked against their pinned sha256 now, before any file is read.
        if "lpips" in self.options.metrics:
            get_lpips_net(self.options.convention.backbone)
        if "dists" in self.options.metrics:
            get_dists_net()
        self.cache = FeatureCache(self.options.cache_mb << 20, self.options.cache_dir)
        self._hash_memo: dict[tuple[str, int, int], str] = {}
        self._queue: list[_NetItem] = []
        self.thumbnails: ThumbnailSet | None = None
        # predictions smaller than the ground truth are read only where the convention resamples to their size
        self._smaller_ok = self.options.convention.resampling == "area"
        """The last `evaluate`'s tiles (None with `thumbnails=False`); `report.write_result` writes them."""

    # ---------------------------------------------------------------- bookkeeping
    def weight_names(self) -> list[str]:
        names = []
        if "lpips" in self.options.metrics:
            b = "alexnet" if self.options.convention.backbone == "alex" else "vgg16"
            names += [b, f"lpips_{self.options.convention.backbone}_v0.1"]
        if "dists" in self.options.metrics:
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
    def _gt_features(self, net: str, items: list[_NetItem], compute: Callable[[], list]):
        """The batch's ground-truth features for `score_pairs`: from the cache, or computed and cached."""
        keys = [self._net_key(it.gt_key, net) for it in items]
        found: dict[str, Any] = {}
        for k in dict.fromkeys(keys):  # unique keys, in order
            found[k] = self.cache.get(k)
        first = {k: keys.index(k) for k in found}
        todo = [first[k] for k, v in found.items() if v is None]
        if todo:
            # The whole batch, not just the missing items: oneDNN picks its kernels by batch size (a crop's
            # features at N=1 differ from N=2 in the last bits), and ground truth run exactly like the
            # prediction makes a prediction equal to the ground truth score exactly 0.
            feats = compute()
            for i in todo:
                found[keys[i]] = _take(feats, i)
                self.cache.put(keys[i], found[keys[i]])
            # Every key computed in this batch (repeated ground truths included, e.g. a frame's albedo and aligned
            # albedo): the batch as computed, each item its own position's features. oneDNN's kernels can give two
            # positions of one batch different last bits for the same input (seen on AVX2, not on AVX-512), so
            # reusing the first copy would make rh-eval differ from score_frame.
            if len(todo) == len(found):
                return feats
        return _cat([found[k] for k in keys])

    def _flush(self) -> None:
        if not self._queue:
            return
        groups: dict[tuple[int, int], list[_NetItem]] = {}
        for it in self._queue:
            groups.setdefault(it.pair.shape, []).append(it)
        self._queue = []
        bs = self.options.batch_size
        for items_all in groups.values():
            for s in range(0, len(items_all), bs):
                items = items_all[s:s + bs]
                values = score_pairs([it.pair for it in items], self.options.convention, self.options.metrics,
                                     reference=lambda net, _pairs, compute: self._gt_features(net, items, compute))
                for i, it in enumerate(items):
                    record_pair_scores(it.scores, it.pair, {m: v[i] for m, v in values.items()})

    def _flush_full_groups(self) -> None:
        """Run every shape group that has a full batch; keep the rest queued."""
        counts: dict[tuple[int, int], int] = {}
        for it in self._queue:
            counts[it.pair.shape] = counts.get(it.pair.shape, 0) + 1
        ready = {s for s, n in counts.items() if n >= self.options.batch_size}
        if len(self._queue) > 8 * self.options.batch_size:  # many odd shapes: bound the memory
            ready = set(counts)
        if not ready:
            return
        keep = [it for it in self._queue if it.pair.shape not in ready]
        self._queue = [it for it in self._queue if it.pair.shape in ready]
        self._flush()
        self._queue = keep

    # ---------------------------------------------------------------- per frame (worker threads)
    def _prepare(self, pf, pred: PredictionIndex, stored: dict, thumb_keys: set,
                 tiles: dict) -> tuple[FrameScores, list[_NetItem]]:
        """Everything about one frame except the networks: read, crop, convert, CPU metrics, and the tiles of a
        frame in the fixed picture selection (`thumb_keys`, into `tiles`). Runs in a worker thread; returns the
        frame's scores so far and its network inputs."""
        conv = self.options.convention
        gt = pf.gt
        frame_pred, frame_gt = read_frame(pf, self.options.metrics, stored=stored, smaller_ok=self._smaller_ok)
        try:
            scores, pairs = prepare_frame(frame_pred, frame_gt, conv, self.options.metrics)
        except CropTooSmallError as exc:
            raise CropTooSmallError(f"{pf.gt.json_path}: {exc}") from None
        if gt.key in thumb_keys:  # while the pixels are in memory
            tiles[gt.key] = frame_tiles(frame_pred, frame_gt, conv)
        items = []
        if pairs:
            frame_id = "|".join([self._file_sha(gt.json_path), self._file_sha(gt.layer("mask.png"))])
            for p in pairs:
                r = p.region
                key = (f"{frame_id}|{self._file_sha(gt.layer(p.source + '.exr'))}|{p.source}|{conv.region_key()}|"
                       f"{r.y0},{r.y1},{r.x0},{r.x1}")
                items.append(_NetItem(scores, p, key))
        return scores, items

    def _workers(self) -> int:
        return self.options.workers or max(1, torch.get_num_threads())

    def check_predictions(self, pred: PredictionIndex) -> dict:
        """Check the whole prediction set before anything is computed, listing every bad file: headers first
        (resolution, channel count, bit depth, format) for every file, then every file decoded in full (corrupt
        data, NaN/Inf) on the worker threads. Returns decoded pixels to reuse, up to `preload_mb`."""
        metrics = self.options.metrics
        image_metrics = any(m in metrics for m in IMAGE_METRICS)
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
                    check_header(path, pf.gt, self._smaller_ok)
                except ImageFileError as exc:
                    problems.append(str(exc))
                else:
                    files.append((path, pf.gt, self._smaller_ok))
        stored: dict[Path, np.ndarray] = {}
        budget, used_bytes = self.options.preload_mb << 20, 0

        def decode(item):
            try:
                return decode_layer(*item)
            except ImageFileError as exc:
                return exc

        with ThreadPoolExecutor(self._workers()) as pool:
            for (path, *_), arr in zip(files, pool.map(decode, files)):
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
                 on_frame: Callable[[int, int], None] | None = None, *,
                 split: str = layout.TEST_SPLIT) -> tuple[dict, list[dict], list[str]]:
        """Evaluate one predictions folder on one split of the dataset (`split`, when `dataset` is a path; a
        `DatasetIndex` carries its own). Returns (result JSON dict, per-frame rows, CSV columns).

        Every prediction file is checked (`check_predictions`) before any metric is computed; nothing is
        returned (or written by the CLI) unless every frame was evaluated."""
        ds = dataset if isinstance(dataset, DatasetIndex) else load_dataset(dataset, protocol, split)
        pred = scan_predictions(pred_root, ds, allow_incomplete=self.options.allow_incomplete)
        conv = self.options.convention
        if conv.relit_with_aligned_albedo and not pred.has_albedo and \
                any(m in self.options.metrics for m in IMAGE_METRICS):
            raise PredictionError(pred.root, [f"convention {conv.name!r} needs the albedo layer "
                                              f"(frame_NNNNNN_albedo.exr or .png): its relit images are rendered "
                                              f"with the albedo aligned to the ground truth, and that albedo is "
                                              f"scored with them"])
        stored = self.check_predictions(pred)
        self.thumbnails = None
        thumb_keys = select_fixed([pf.gt for pf in pred.frames]) if self.options.thumbnails else set()
        tiles: dict[str, dict | None] = {}
        self._cache_start = {k: getattr(self.cache, k) for k in ("hits", "disk_hits", "misses")}
        opts = self.options
        conv = opts.convention
        frames: list[FrameScores] = []  # in dataset order; LPIPS/DISTS filled in as their batches run
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
            pending = deque(pool.submit(self._prepare, pf, pred, stored, thumb_keys, tiles) for pf in islice(todo, ahead))
            while pending:
                scores, items = pending.popleft().result()
                if overlap:
                    pending.extend(pool.submit(self._prepare, pf, pred, stored, thumb_keys, tiles) for pf in islice(todo, 1))
                frames.append(scores)
                self._queue.extend(items)
                if len(self._queue) >= opts.batch_size:
                    self._flush_full_groups()
                if not overlap and not pending:
                    pending.extend(pool.submit(self._prepare, pf, pred, stored, thumb_keys, tiles) for pf in islice(todo, ahead))
                if bar is not None:
                    bar.update(1)
                if on_frame is not None:
                    on_frame(len(frames), len(pred.frames))
            self._flush()
        except BaseException:
            self._queue = []
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            if bar is not None:
                bar.close()
        cols = metric_columns(opts.metrics, albedo=pred.has_albedo, aligned=conv.align_albedo != "none",
                              image_aligned=conv.align_image != "none",
                              normal=pred.has_normal)
        rows = []
        for pf, scores in zip(pred.frames, frames):
            row = {"subject": pf.gt.subject, "frame": pf.gt.index, **scores.columns()}
            if pf.gt.view is not None:  # a multi-view split's camera (single-camera rows keep their columns)
                row = {"subject": pf.gt.subject, "view": pf.gt.view, "frame": pf.gt.index, **scores.columns()}
            for c in cols:  # undefined (empty mask) is already None: stored as null, counted, never averaged
                row.setdefault(c, None)
            rows.append(row)
        result = self._result(ds, pred, rows, cols)
        if self.options.thumbnails:
            self.thumbnails = self._thumbnails(pred, rows, cols, thumb_keys, tiles)
        return result, rows, cols

    def _thumbnails(self, pred: PredictionIndex, rows: list[dict], cols: list[str], fixed: set[str],
                    tiles: dict) -> ThumbnailSet:
        """The fixed frames' tiles (made in the loop) and this method's best, median and worst, read again here:
        which frames they are is known only now."""
        def again(pf):
            return frame_tiles(*read_frame(pf, self.options.metrics, smaller_ok=self._smaller_ok),
                               self.options.convention)

        return collect_thumbnails(pred.frames, rows, cols, fixed, tiles, again)

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
            "dataset": {"root": str(ds.root), "protocol": ds.protocol, "split": ds.split,
                        "manifest_sha256": ds.manifest_sha256, "n_frames": len(ds.frames),
                        "content_identity": layout.split_identity(ds.root, ds.protocol, ds.split),
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
