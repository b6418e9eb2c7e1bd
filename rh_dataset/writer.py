"""Frame writer: layers → files (EXR + PNG previews), the frame JSON written last, manifest, contact sheets.

A frame is complete when its JSON exists and every file it lists has the sha256 the JSON records. Every file is
written atomically, the JSON after all layers, so a run killed at any moment leaves either a complete frame or
one that `frame_is_complete` rejects and a rerun redoes.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
from PIL import Image

from rh_common.colourspace import quantize8, srgb_encode, to_display
from rh_common.imageio import read_json, sha256_file, write_exr, write_json, write_png

__all__ = [
    "FRAME_FORMAT",
    "frame_stem",
    "layer_files",
    "write_frame",
    "frame_is_complete",
    "write_manifest",
    "contact_sheet",
]

FRAME_FORMAT = "rh-frame/1"


def frame_stem(index: int) -> str:
    return f"frame_{index:06d}"


def layer_files(index: int, layer: str) -> list[str]:
    """File names one layer occupies (see docs/ARCHITECTURE.md, "Dataset layout")."""
    s = frame_stem(index)
    return {
        "image": [f"{s}_image.exr", f"{s}_image.png"],
        "mask": [f"{s}_mask.png"],
        "albedo": [f"{s}_albedo.exr", f"{s}_albedo.png"],
        "normal": [f"{s}_normal.exr", f"{s}_normal.png"],
        "depth": [f"{s}_depth.exr"],
    }[layer]


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


def write_frame(split_dir: str | os.PathLike, index: int, layers: Mapping[str, np.ndarray], meta: dict) -> Path:
    """Write every layer then the frame JSON (`meta` plus the file list with checksums). Returns the JSON path."""
    split_dir = Path(split_dir)
    exposure = float(meta["exposure"])
    listed: dict[str, dict[str, str]] = {}
    for layer, data in layers.items():
        for name, digest in _encode_layer(split_dir, index, layer, data, exposure).items():
            listed[name] = {"layer": layer, "sha256": digest}
    record = dict(meta)
    if "image" in layers:
        # Reported, never hidden: the count of isolated over-bright pixels of the image as written (no clamping).
        from rh_dataset.render.passes import count_fireflies

        record["render"] = {**record.get("render", {}), "fireflies": count_fireflies(layers["image"])}
    record["format"] = FRAME_FORMAT
    record["index"] = index
    record["files"] = listed
    json_path = split_dir / f"{frame_stem(index)}.json"
    write_json(json_path, record)
    return json_path


def frame_is_complete(split_dir: str | os.PathLike, index: int, expected_layers: Iterable[str]) -> bool:
    """True only if the frame JSON exists, lists exactly the expected layers' files, and every checksum matches."""
    split_dir = Path(split_dir)
    json_path = split_dir / f"{frame_stem(index)}.json"
    if not json_path.is_file():
        return False
    try:
        files = read_json(json_path)["files"]
    except (ValueError, KeyError, TypeError):
        return False
    wanted = {f for layer in expected_layers for f in layer_files(index, layer)}
    if set(files) != wanted:
        return False
    for name, info in files.items():
        p = split_dir / name
        if not p.is_file() or sha256_file(p) != info.get("sha256"):
            return False
    return True


def write_manifest(root: str | os.PathLike) -> Path:
    """sha256 and size of every file under `root` but the manifest itself and temporaries, sorted by path."""
    root = Path(root)
    entries = {}
    for p in sorted(root.rglob("*")):
        if not p.is_file() or p.name == "manifest.json" or p.name.endswith(".tmp"):
            continue
        rel = p.relative_to(root).as_posix()
        entries[rel] = {"sha256": sha256_file(p), "bytes": p.stat().st_size}
    out = root / "manifest.json"
    write_json(out, {"format": "rh-manifest/1", "files": entries})
    return out


def contact_sheet(split_dir: str | os.PathLike, indices: list[int], layers: Iterable[str], *, tile: int = 128,
                  max_frames: int = 24) -> Path | None:
    """A grid of PNG previews: one row per shown frame group, columns = image/albedo/normal/mask when present."""
    split_dir = Path(split_dir)
    cols = [l for l in ("image", "albedo", "normal", "mask") if l in set(layers)]
    if not indices or not cols:
        return None
    if len(indices) > max_frames:
        pick = np.linspace(0, len(indices) - 1, max_frames).round().astype(int)
        indices = [indices[i] for i in sorted(set(pick))]
    per_row = max(1, 8 // len(cols)) if len(cols) > 1 else 8
    n_rows = -(-len(indices) // per_row)
    gap = 2
    W = per_row * (len(cols) * tile + gap)
    sheet = Image.new("RGB", (W, n_rows * (tile + gap)), (24, 24, 24))
    for k, idx in enumerate(indices):
        r, c = divmod(k, per_row)
        for j, layer in enumerate(cols):
            name = [f for f in layer_files(idx, layer) if f.endswith(".png")][0]
            with Image.open(split_dir / name) as im:
                im = im.convert("RGB")
                im.thumbnail((tile, tile))
                x = c * (len(cols) * tile + gap) + j * tile + (tile - im.width) // 2
                y = r * (tile + gap) + (tile - im.height) // 2
                sheet.paste(im, (x, y))
    out = split_dir / "contact_sheet.png"
    write_png(out, np.asarray(sheet))
    return out
