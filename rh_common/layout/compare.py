"""Two datasets compared frame by frame and layer by layer, and whether they are the same benchmark.

In: two dataset roots (`rh-verify A --against B`). Out: a `Comparison`: per split and layer (file kind, e.g.
`image.exr`) the largest absolute difference and the lowest per-frame PSNR, the frames that differ, and the
verdict: identical (same content identity), the same benchmark within rounding (`TOLERANCE`; the frame JSON's
cameras, poses and lights too, `metadata_difference`), the same benchmark
within sampling noise (`NOISE_TOLERANCE`: a few pixels' paths took another course, the rest within rounding), or
different. Its `to_json()` is the record `rh-leaderboard --comparison` reads to put results of the two datasets side
by side.

PSNR of one decoded file against the other's: 10 log10(peak^2 / MSE), peak = max |A| of the file (so it is
scale-free: HDR radiance, depth in metres and 8-bit PNGs alike); inf when equal. A pixel *diverged* when one of its
channels differs by more than `TOLERANCE` allows one pixel: 1e-5 * peak for a float file (a single such pixel alone
would bring the file to 100 dB), more than one level for an 8-bit one. Why these numbers:
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

__all__ = ["COMPARISON_FORMAT", "TOLERANCE", "NOISE_TOLERANCE", "TIERS", "LayerDiff", "Comparison", "compare_datasets",
           "metadata_difference", "read_comparison"]

COMPARISON_FORMAT = "rh-comparison/1"
# Within tolerance: every float layer of every frame at >= min_psnr_db against the other dataset's, every 8-bit
# layer off by at most max_8bit_levels, and the same frames with the same cameras, poses and lights: the same keys,
# strings and integers, and every float of them within metadata_rel of the larger magnitude or metadata_abs. Floats
# in the frame JSON are float64 results of BLAS products (pose matrices, SH coefficients), and another CPU's BLAS
# kernel changes their last bits (OpenBLAS's Zen against its SkylakeX kernel: up to 1e-14 relative, the light's
# scale 8e-9); 1e-6 is a micrometre at the camera's distance and a microradian of a joint.
TOLERANCE = {"min_psnr_db": 100.0, "max_8bit_levels": 1, "metadata_rel": 1e-6, "metadata_abs": 1e-9}
# Within sampling noise: as TOLERANCE, except that in each file up to this fraction of the pixels may have diverged
# (their paths took another course: a ray grazing a hair curve hits it at one LLVM vector width and misses at the
# other), whatever their difference. Measured 8 vs 16 lanes, strand-hair subjects: at most 0.81 % of a file's pixels
# (docs/ARCHITECTURE.md, "Content identity"); 2 % leaves room for denser hair, and a change of the data that
# reaches more pixels than that (any offset, any other light, pose or camera) is outside.
NOISE_TOLERANCE = {**TOLERANCE, "max_diverged_fraction": 0.02}
TIERS = ("rounding", "noise")


@dataclass
class LayerDiff:
    max_abs: float = 0.0
    min_psnr_db: float = math.inf
    frames: int = 0
    frames_differing: int = 0
    is_8bit: bool = False
    pixels: int = 0                      # over every frame of the layer
    pixels_diverged: int = 0
    max_diverged_fraction: float = 0.0   # the largest fraction of diverged pixels in one frame's file

    def within(self, tier: str = "rounding") -> bool:
        """Within rounding (`TOLERANCE`), or with tier "noise" within sampling noise (`NOISE_TOLERANCE`)."""
        if self.is_8bit:
            rounding = self.max_abs <= TOLERANCE["max_8bit_levels"]
        else:
            rounding = self.min_psnr_db >= TOLERANCE["min_psnr_db"]
        if rounding or tier == "rounding":
            return rounding
        return self.max_diverged_fraction <= NOISE_TOLERANCE["max_diverged_fraction"]

    def to_json(self) -> dict:
        return {"max_abs": self.max_abs, "min_psnr_db": _num(self.min_psnr_db), "frames": self.frames,
                "frames_differing": self.frames_differing, "is_8bit": self.is_8bit, "pixels": self.pixels,
                "pixels_diverged": self.pixels_diverged, "max_diverged_fraction": self.max_diverged_fraction}


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
    metadata_frames_differing: int = 0  # frames whose cameras, poses or lights differ within rounding only
    metadata_max: float = 0.0           # the largest such float difference, in units of the tolerance (<= 1)

    @property
    def identical(self) -> bool:
        return (not self.mismatches and not self.frames_differing and self.identity_a is not None
                and self.identity_b is not None and self.identity_a["dataset"] == self.identity_b["dataset"])

    tier: str = "noise"  # the loosest tier that counts as the same benchmark ("rounding" or "noise")

    def within(self, tier: str) -> bool:
        return not self.mismatches and all(d.within(tier) for d in self.layers.values())

    @property
    def within_rounding(self) -> bool:
        return self.within("rounding")

    @property
    def within_tolerance(self) -> bool:
        """The same benchmark at `tier`: within rounding, or (tier "noise") within sampling noise."""
        return self.within(self.tier)

    @property
    def verdict(self) -> str:
        if self.identical:
            return "identical (same content identity)"
        if self.within_rounding:
            return (f"the same benchmark within rounding (float layers >= {TOLERANCE['min_psnr_db']:g} dB, "
                    f"8-bit layers within {TOLERANCE['max_8bit_levels']} level)")
        if self.within_tolerance:
            worst = max(d.max_diverged_fraction for d in self.layers.values())
            return (f"the same benchmark within sampling noise (up to {100 * worst:.2f} % of a file's pixels took "
                    f"another path, at most {100 * NOISE_TOLERANCE['max_diverged_fraction']:g} %; the rest within "
                    f"rounding)")
        if self.tier == "rounding" and self.within("noise"):
            return "NOT the same benchmark within rounding (it is within sampling noise: --tolerance noise)"
        return "NOT the same benchmark"

    def to_json(self) -> dict:
        def ident(i):
            return None if i is None else {"dataset": i["dataset"], "splits": i["splits"]}

        tolerance = NOISE_TOLERANCE if self.tier == "noise" else TOLERANCE
        return {"format": COMPARISON_FORMAT, "tolerance": {**tolerance, "tier": self.tier},
                "a": {"root": str(self.a), "identity": ident(self.identity_a)},
                "b": {"root": str(self.b), "identity": ident(self.identity_b)},
                "identical": self.identical, "within_tolerance": self.within_tolerance,
                "within_rounding": self.within_rounding, "verdict": self.verdict,
                "layers": {k: v.to_json() for k, v in sorted(self.layers.items())},
                "frames_differing": self.frames_differing, "mismatches": self.mismatches,
                "metadata": {"frames_differing_within_rounding": self.metadata_frames_differing,
                             "max_difference_in_tolerances": self.metadata_max}}

    def write(self, path: str | os.PathLike) -> Path:
        write_json(path, self.to_json())
        return Path(path)


def _psnr(x: np.ndarray, y: np.ndarray) -> float:
    mse = float(np.mean((x - y) ** 2))
    if mse == 0.0:
        return math.inf
    peak = float(np.max(np.abs(x)))
    return 10.0 * math.log10(peak * peak / mse) if peak > 0 else -math.inf


def _diverged(x: np.ndarray, y: np.ndarray, is_8bit: bool) -> np.ndarray:
    """Per pixel (H, W): does any channel differ by more than rounding allows one pixel (module docstring)?"""
    d = np.abs(x - y).reshape(x.shape[0], x.shape[1], -1).max(axis=-1)
    if is_8bit:
        limit = TOLERANCE["max_8bit_levels"]
    else:
        limit = 10 ** (-TOLERANCE["min_psnr_db"] / 20) * float(np.max(np.abs(x)))
    return d > limit


def metadata_difference(x, y) -> float:
    """How far two frame-JSON values (a semantic key's) are apart: 0.0 when equal, the largest difference of two
    floats in units of the tolerance (|a - b| / max(metadata_rel * max(|a|, |b|), metadata_abs): within rounding
    when <= 1), inf when they differ otherwise (keys, lengths, strings, integers, booleans, None)."""
    if isinstance(x, dict) and isinstance(y, dict):
        if set(x) != set(y):
            return math.inf
        return max((metadata_difference(x[k], y[k]) for k in x), default=0.0)
    if isinstance(x, list) and isinstance(y, list):
        if len(x) != len(y):
            return math.inf
        return max((metadata_difference(u, v) for u, v in zip(x, y)), default=0.0)
    if isinstance(x, float) and isinstance(y, float) and not (math.isnan(x) or math.isnan(y)):
        if x == y:
            return 0.0
        limit = max(TOLERANCE["metadata_rel"] * max(abs(x), abs(y)), TOLERANCE["metadata_abs"])
        return abs(x - y) / limit
    return 0.0 if (type(x) is type(y) and x == y) else math.inf


def compare_datasets(a: str | os.PathLike, b: str | os.PathLike, identity_a: dict | None = None,
                     identity_b: dict | None = None, progress: bool = False, tier: str = "noise") -> Comparison:
    """Decode every frame of both datasets and compare them (the identities are recorded in the result). `tier`:
    what the verdict accepts as the same benchmark, "rounding" (`TOLERANCE`) or "noise" (`NOISE_TOLERANCE`)."""
    from tqdm import tqdm

    from rh_common.identity import SEMANTIC_KEYS, canonical_json

    a, b = Path(a), Path(b)
    if tier not in TIERS:
        raise ValueError(f"tolerance tier {tier!r}: choose one of {', '.join(TIERS)}")
    cmp = Comparison(a, b, identity_a, identity_b, tier=tier)
    rel_a = {p.relative_to(a).as_posix() for p in iter_frame_jsons(a)}
    rel_b = {p.relative_to(b).as_posix() for p in iter_frame_jsons(b)}
    cmp.mismatches += [f"{r}: only in {a}" for r in sorted(rel_a - rel_b)]
    cmp.mismatches += [f"{r}: only in {b}" for r in sorted(rel_b - rel_a)]
    for rel in tqdm(sorted(rel_a & rel_b), disable=not progress, unit="frame", desc="compare"):
        ra, rb = read_json(a / rel), read_json(b / rel)
        metadata_differs = False
        for k in SEMANTIC_KEYS:
            if canonical_json(ra.get(k)) == canonical_json(rb.get(k)):
                continue
            off = metadata_difference(ra.get(k), rb.get(k))
            if off > 1.0:
                cmp.mismatches.append(f"{rel}: '{k}' differs (another camera, pose or light)")
            else:
                metadata_differs = True
                cmp.metadata_max = max(cmp.metadata_max, off)
        cmp.metadata_frames_differing += metadata_differs
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
            pixels = x.shape[0] * x.shape[1]
            d.pixels += pixels
            if not np.array_equal(x, y):
                diverged = int(np.count_nonzero(_diverged(x, y, d.is_8bit)))
                d.pixels_diverged += diverged
                d.max_diverged_fraction = max(d.max_diverged_fraction, diverged / pixels)
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
