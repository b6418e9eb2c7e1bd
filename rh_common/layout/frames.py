"""Writing one frame's layers and its JSON, and telling a complete frame from an interrupted one.

In: a split folder, a frame index, the layers as float arrays (image: linear radiance (H, W, 3); mask: coverage
(H, W) in [0, 1]; albedo: linear (H, W, 3); normal: OpenGL camera space (H, W, 3), zero off the body; depth:
camera-space z (H, W)) and the frame's metadata (every `FrameRecord` field but `index`, `files`, `format`).
Out: the layer files (EXR + 8-bit PNG previews) and `frame_%06d.json` listing each file with its sha256.

A frame is complete when its JSON exists and every file it lists has the sha256 the JSON records. Every file is
written atomically, the JSON after all layers, so a run killed at any moment leaves either a complete frame or
one that `frame_is_complete` rejects and a rerun redoes.
"""
from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from rh_common.colourspace import quantize8, srgb_encode, to_display
from rh_common.imageio import read_json, sha256_file, write_exr, write_png

from .paths import frame_json_path, layer_file_name
from .record import FRAME_FORMAT, FileEntry, FrameRecord, write_frame_record

__all__ = ["LAYERS", "layer_files", "write_frame", "frame_is_complete"]

# The files each layer occupies, in the order they are written: the data first, then its preview.
_LAYER_EXTS = {
    "image": (("image", "exr"), ("image", "png")),
    "mask": (("mask", "png"),),
    "albedo": (("albedo", "exr"), ("albedo", "png")),
    "normal": (("normal", "exr"), ("normal", "png")),
    "depth": (("depth", "exr"),),
}
LAYERS = tuple(_LAYER_EXTS)


def layer_files(index: int, layer: str) -> list[str]:
    """File names one layer occupies (see docs/ARCHITECTURE.md, "Dataset layout")."""
    if layer not in _LAYER_EXTS:
        raise ValueError(f"unknown layer {layer!r}: one of {LAYERS}")
    return [layer_file_name(index, name, ext) for name, ext in _LAYER_EXTS[layer]]


def _encode_layer(split_dir: Path, index: int, layer: str, data: np.ndarray, exposure: float) -> dict[str, str]:
    files = layer_files(index, layer)
    paths = [split_dir / f for f in files]
    if not np.all(np.isfinite(data)):
        raise ValueError(f"{paths[0]}: layer {layer!r} has {int(np.sum(~np.isfinite(data)))} NaN/Inf values; "
                         "refusing to write it (the renderer produced an invalid frame)")
    if layer == "image":
        write_exr(paths[0], data)
        write_png(paths[1], quantize8(to_display(data, exposure)))
    elif layer == "mask":
        write_png(paths[0], quantize8(data))
    elif layer == "albedo":
        write_exr(paths[0], data)
        write_png(paths[1], quantize8(srgb_encode(data)))
    elif layer == "normal":
        write_exr(paths[0], data)
        inside = np.any(data != 0.0, axis=-1, keepdims=True)
        write_png(paths[1], np.where(inside, quantize8((data + 1.0) * 0.5), 0).astype(np.uint8))
    elif layer == "depth":
        write_exr(paths[0], data)
    return {f: sha256_file(p) for f, p in zip(files, paths)}


def write_frame(split_dir: str | os.PathLike, index: int, layers: Mapping[str, np.ndarray], meta: Mapping,
                workers: int | None = None) -> Path:
    """Write every layer then the frame JSON (`meta` plus the file list with checksums). Returns the JSON path.
    `workers`: threads encoding the layers (None: one per layer, at most one per core; 1: one after another).

    `meta` is checked as a `FrameRecord`, and the layers against its width and height, before any file is written,
    so a bad record leaves no orphan layers."""
    split_dir = Path(split_dir)
    record = FrameRecord.from_json({**meta, "format": FRAME_FORMAT, "index": index, "files": {}})
    for layer, data in layers.items():
        # rh-eval and rana size everything from the record's width/height: a layer of another size is a bug here.
        if tuple(np.shape(data)[:2]) != (record.height, record.width):
            raise ValueError(f"{split_dir}: layer {layer!r} is {np.shape(data)[:2]} (H, W) but the frame record says "
                             f"{record.width}x{record.height} (WxH)")
    items = list(layers.items())

    def encode(item):
        return _encode_layer(split_dir, index, item[0], item[1], float(record.exposure))

    # The layers are encoded side by side: zlib, OpenEXR and hashlib release the GIL while they work, and on a GPU
    # the writer was the larger part of a `standard` frame (bench/bench_render_stage.py, docs/TRADEOFFS.md "The GPU
    # path"). Threads rather than processes: the arrays are not copied. Same files, same bytes, in any order; a
    # layer that fails leaves the others' files complete (atomic) and no JSON, so the frame is redone on a rerun.
    workers = min(len(items), os.cpu_count() or 1) if workers is None else max(1, min(len(items), int(workers)))
    if workers > 1:
        pool = ThreadPoolExecutor(workers, thread_name_prefix="write_frame")
        try:
            encoded = list(pool.map(encode, items))
        finally:  # on an error or a stop, layers not yet started are not started
            pool.shutdown(wait=True, cancel_futures=True)
    else:
        encoded = [encode(item) for item in items]
    listed = {name: FileEntry(layer, digest) for (layer, _), files in zip(items, encoded)
              for name, digest in files.items()}
    return write_frame_record(frame_json_path(split_dir, index), dataclasses.replace(record, files=listed))


def frame_is_complete(split_dir: str | os.PathLike, index: int, expected_layers: Iterable[str]) -> bool:
    """True only if the frame JSON exists, lists exactly the expected layers' files, and every checksum matches."""
    split_dir = Path(split_dir)
    json_path = frame_json_path(split_dir, index)
    if not json_path.is_file():
        return False
    try:
        files = read_json(json_path)["files"]
        wanted = {f for layer in expected_layers for f in layer_files(index, layer)}
    except (ValueError, KeyError, TypeError):
        return False
    if set(files) != wanted:
        return False
    for name, info in files.items():
        p = split_dir / name
        if not isinstance(info, dict) or not p.is_file() or sha256_file(p) != info.get("sha256"):
            return False
    return True
