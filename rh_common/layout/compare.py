"""Two datasets compared frame by frame and layer by layer, and whether they are the same benchmark.

In: two dataset roots (`rh-verify A --against B`). Out: a `Comparison`: per split and layer (file kind, e.g.
`image.exr`) the largest absolute difference and the lowest per-frame PSNR, the frames that differ, and the
verdict: identical (same content identity), the same benchmark within `TOLERANCE`, or different. Its `to_json()`
is the record `rh-leaderboard --comparison` reads to put results of the two datasets side by side.

PSNR of one decoded file against the other's: 10 log10(peak^2 / MSE), peak = max |A| of the file (so it is
scale-free: HDR radiance, depth in metres and 8-bit PNGs alike); inf when equal. Why these numbers:
docs/ARCHITECTURE.md, "Content identity".
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rh_common.identity import frame_arrays
from rh_common.imageio import read_json, write_json

from .paths import iter_frame_jsons

__all__ = ["COMPARISON_FORMAT", "TOLERANCE", "LayerDiff", "Comparison", "compare_datasets", "read_comparison"]

COMPARISON_FORMAT = "rh-comparison/1"
# Within tolerance: every float layer of every frame at >= min_psnr_db against the other dataset's, every 8-bit
# layer off by at most max_8bit_levels, and the same frames with the same cameras, poses and lights.
TOLERANCE = {"min_psnr_db": 100.0, "max_8bit_levels": 1}


@dataclass
class LayerDiff:
    max_abs: float = 0.0
    min_psnr_db: float = math.inf
    frames: int = 0
    frames_differing: int = 0
    is_8bit: bool = False

    def within(self) -> bool:
        if self.is_8bit:
            return self.max_abs <= TOLERANCE["max_8bit_levels"]
        return self.min_psnr_db >= TOLERANCE["min_psnr_db"]

    def to_json(self) -> dict:
        return {"max_abs": self.max_abs, "min_psnr_db": _num(self.min_psnr_db), "frames": self.frames,
                "frames_differing": self.frames_differing, "is_8bit": self.is_8bit}


def _num(x: float):
    return "inf" if math.isinf(x) else x


@dataclass
class Comparison:
    a: Path
    b: Path
    identity_a: dict | None
    identity_b: dict | None
    layers: dict[str, LayerDiff] = field(default_factory=dict)  # "protocol_a/test/image.exr" -> difference
    frames_differing: list[str] = field(default_factory=list)   # frame JSON paths whose layers differ
    mismatches: list[str] = field(default_factory=list)         # frames missing on one side, or other metadata

    @property
    def identical(self) -> bool:
        return (not self.mismatches and not self.frames_differing and self.identity_a is not None
                and self.identity_b is not None and self.identity_a["dataset"] == self.identity_b["dataset"])

    @property
    def within_tolerance(self) -> bool:
        return not self.mismatches and all(d.within() for d in self.layers.values())

    @property
    def verdict(self) -> str:
        if self.identical:
            return "identical (same content identity)"
        if self.within_tolerance:
            return (f"the same benchmark within tolerance (float layers >= {TOLERANCE['min_psnr_db']:g} dB, "
                    f"8-bit layers within {TOLERANCE['max_8bit_levels']} level)")
        return "NOT the same benchmark"

    def to_json(self) -> dict:
        def ident(i):
            return None if i is None else {"dataset": i["dataset"], "splits": i["splits"]}

        return {"format": COMPARISON_FORMAT, "tolerance": TOLERANCE,
                "a": {"root": str(self.a), "identity": ident(self.identity_a)},
                "b": {"root": str(self.b), "identity": ident(self.identity_b)},
                "identical": self.identical, "within_tolerance": self.within_tolerance,
                "layers": {k: v.to_json() for k, v in sorted(self.layers.items())},
                "frames_differing": self.frames_differing, "mismatches": self.mismatches}

    def write(self, path: str | os.PathLike) -> Path:
        write_json(path, self.to_json())
        return Path(path)


def _psnr(x: np.ndarray, y: np.ndarray) -> float:
    mse = float(np.mean((x - y) ** 2))
    if mse == 0.0:
        return math.inf
    peak = float(np.max(np.abs(x)))
    return 10.0 * math.log10(peak * peak / mse) if peak > 0 else -math.inf


def compare_datasets(a: str | os.PathLike, b: str | os.PathLike, identity_a: dict | None = None,
                     identity_b: dict | None = None, progress: bool = False) -> Comparison:
    """Decode every frame of both datasets and compare them (the identities are recorded in the result)."""
    from tqdm import tqdm

    from rh_common.identity import SEMANTIC_KEYS, canonical_json

    a, b = Path(a), Path(b)
    cmp = Comparison(a, b, identity_a, identity_b)
    rel_a = {p.relative_to(a).as_posix() for p in iter_frame_jsons(a)}
    rel_b = {p.relative_to(b).as_posix() for p in iter_frame_jsons(b)}
    cmp.mismatches += [f"{r}: only in {a}" for r in sorted(rel_a - rel_b)]
    cmp.mismatches += [f"{r}: only in {b}" for r in sorted(rel_b - rel_a)]
    for rel in tqdm(sorted(rel_a & rel_b), disable=not progress, unit="frame", desc="compare"):
        ra, rb = read_json(a / rel), read_json(b / rel)
        for k in SEMANTIC_KEYS:
            if canonical_json(ra.get(k)) != canonical_json(rb.get(k)):
                cmp.mismatches.append(f"{rel}: '{k}' differs (another camera, pose or light)")
        if set(ra["files"]) != set(rb["files"]):
            cmp.mismatches.append(f"{rel}: the two frames list other files")
            continue
        fa, fb = frame_arrays(a / rel, ra), frame_arrays(b / rel, rb)
        split, differs = "/".join(rel.split("/")[1:3]), False  # a multi-view split's cameras: one row
        for name, xa in fa.items():
            xb = fb[name]
            d = cmp.layers.setdefault(f"{split}/{name.split('_', 2)[2]}", LayerDiff(is_8bit=xa.dtype == np.uint8))
            d.frames += 1
            if xa.shape != xb.shape:
                cmp.mismatches.append(f"{rel}: {name} is {xa.shape} in one, {xb.shape} in the other")
                continue
            x, y = xa.astype(np.float64), xb.astype(np.float64)
            if not np.array_equal(x, y):
                d.frames_differing += 1
                differs = True
                d.max_abs = max(d.max_abs, float(np.max(np.abs(x - y))))
                d.min_psnr_db = min(d.min_psnr_db, _psnr(x, y))
        if differs:
            cmp.frames_differing.append(rel)
    return cmp


def read_comparison(path: str | os.PathLike) -> dict:
    """A record `Comparison.write` wrote; ValueError naming the file if it is not one."""
    data = read_json(path)
    if not isinstance(data, dict) or data.get("format") != COMPARISON_FORMAT:
        raise ValueError(f"{path}: not an {COMPARISON_FORMAT} record (write one with rh-verify A --against B "
                         f"--record FILE)")
    return data
