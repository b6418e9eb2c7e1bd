"""The content identity of a benchmark: a digest of what a method sees and is scored on, not of file bytes.

In: a frame JSON (its folder holds the layer files it lists). Out: the frame's digest, and digests combining
frames into a split and splits into a dataset (`combine`). docs/ARCHITECTURE.md, "Content identity".

A frame's digest covers
- its semantic record: `subject`, `protocol`, `split`, `index`, `width`, `height`, `exposure`, `camera`, `body`,
  `light` (and `view`, the camera of a multi-view frame, where there is one) as canonical JSON (sorted keys, no
  spaces, floats as Python writes them back: the shortest repr that reads back the same double, which is what
  `rh_common.imageio.write_json` wrote);
- every file it lists, decoded (EXR: float32, PNG: its stored integers), as canonical array bytes: the file name, dtype
  (little-endian), shape, then the values in C order.
Not covered: `versions` (what ran: recorded, and two package sets that give the same pixels give the same
benchmark), `render` (how the pixels were made: the pixels themselves are covered) and `files` (byte checksums:
another EXR or PNG encoder writes other bytes for the same values). So two datasets have the same identity exactly
when a method reading them gets the same arrays and the same cameras, poses and lights.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from rh_common.imageio import read_exr, read_json, read_png

__all__ = ["IDENTITY_FORMAT", "SEMANTIC_KEYS", "canonical_json", "array_bytes", "frame_arrays", "frame_digest",
           "combine"]

IDENTITY_FORMAT = "rh-content/1"
SEMANTIC_KEYS = ("subject", "protocol", "split", "index", "width", "height", "exposure", "camera", "body", "light",
                 "view")  # "view": a multi-view frame's camera; absent from protocols a and b (their digests unchanged)


def canonical_json(obj: Any) -> bytes:
    """Sorted keys, no whitespace, UTF-8; NaN/Inf refused (JSON has none)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode()


def array_bytes(a: np.ndarray) -> bytes:
    """dtype (little-endian) and shape as a header, then the values in C order: the same array gives the same bytes
    whatever its memory layout or the byte order of the machine."""
    a = np.ascontiguousarray(a)
    a = a.astype(a.dtype.newbyteorder("<"), copy=False)
    header = canonical_json({"dtype": a.dtype.str, "shape": list(a.shape)})
    return len(header).to_bytes(4, "little") + header + a.tobytes(order="C")


def frame_arrays(json_path: str | os.PathLike, record: Mapping[str, Any] | None = None) -> dict[str, np.ndarray]:
    """Every file a frame JSON lists, decoded, by file name (sorted). `record`: the JSON already read."""
    json_path = Path(json_path)
    record = read_json(json_path) if record is None else record
    out = {}
    for name in sorted(record["files"]):
        p = json_path.parent / name
        out[name] = read_exr(p) if name.endswith(".exr") else read_png(p)
    return out


def frame_digest(json_path: str | os.PathLike) -> str:
    """sha256 (hex) of a frame's semantic record and decoded layers (module docstring)."""
    record = read_json(json_path)
    h = hashlib.sha256(IDENTITY_FORMAT.encode() + b"\0")
    h.update(canonical_json({k: record[k] for k in SEMANTIC_KEYS if k in record}))
    for name, a in frame_arrays(json_path, record).items():
        h.update(canonical_json(name))
        h.update(array_bytes(a))
    return h.hexdigest()


def combine(digests: Mapping[str, str]) -> str:
    """One digest of named digests (frames of a split, splits of a dataset), independent of mapping order."""
    doc = {"format": IDENTITY_FORMAT, "parts": dict(sorted(digests.items()))}
    return hashlib.sha256(canonical_json(doc)).hexdigest()
