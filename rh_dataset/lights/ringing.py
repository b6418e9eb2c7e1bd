"""Ringing in downsampled environment maps: decoding a base64 EXR data-URI module, measuring the ringing,
repairing it without changing the light.

In: a JavaScript module ``export default 'data:application/exr;base64,...'`` (how npm's `@pmndrs/assets` ships
its maps) or an EXR file; out: an equirectangular float32 map, its `RingingStats`, the repaired map.

Where the negatives come from (measured on `@pmndrs/assets` 1.7.0): the package made its 512x256 maps with
ImageMagick's ``-resize`` (a Lanczos windowed-sinc filter when shrinking) and DWAB compression. The negative
pixels are the filter's negative lobes around a sun or a lamp (down to -13% of the peak): PIL's Lanczos resize of
the package's source maps gives the same negatives, pixel for pixel, within 0.7% of the peak; DWAB only
quantises. The filter keeps local integrals, so clamping the negatives to 0 adds light: up to +13% of a whole
map's power and 18% error in its SH. `repair_ringing` instead sets a block's negatives to 0 and rescales its
positive pixels so that the block's solid-angle-weighted integral (per channel) is unchanged: 8x8 blocks
(5.6° at 512 wide), then 16x16 and 32x32 where a lobe falls in a block of its own. A 32x32 block still holding
more negative than positive light is not ringing around a non-negative signal: `check_ringing` refuses the map.
"""
from __future__ import annotations

import base64
import binascii
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rh_common import sh
from rh_common.colourspace import luminance
from rh_common.imageio import ImageFileError, read_exr

from .library import HdriError

__all__ = ["RING_BLOCK", "REPAIR_BLOCKS", "RingingStats", "decode_exr_module", "measure_ringing",
           "check_ringing", "repair_ringing"]

RING_BLOCK = 8  # the scale at which ringing is counted and first repaired (a Lanczos-3 lobe spans ~3 pixels)
# A lobe cut off from its peak by a block edge leaves a net-negative block; the repair then balances it over the
# 16x16 or 32x32 block around it (11° or 22° at 512 wide).
REPAIR_BLOCKS = (RING_BLOCK, 16, 32)
_MODULE_RE = re.compile(rb"\s*export\s+default\s+(['\"])data:application/(?:x-)?exr;base64,([A-Za-z0-9+/=]+)\1;?\s*")


def decode_exr_module(path: str | Path) -> np.ndarray:
    """The float32 (H, W, 3) map inside a data-URI JavaScript module (or a plain .exr file).

    Raises HdriError, one line naming the file, for a module that is not such a data URI, base64 that does not
    decode, an EXR OpenEXR cannot read, a non-RGB image or a non-equirectangular size.
    """
    path = Path(path)
    if not path.is_file():
        raise HdriError(f"{path}: no such file; run `npm pack @pmndrs/assets` and point --package at it")
    raw = path.read_bytes()
    if path.suffix.lower() == ".exr":
        data = raw
    else:
        m = _MODULE_RE.fullmatch(raw)
        if m is None:
            raise HdriError(f"{path}: not a module of the form export default 'data:application/exr;base64,...'; "
                            f"use the package's hdri/*.exr.js files")
        try:
            data = base64.b64decode(m.group(2), validate=True)
        except (binascii.Error, ValueError) as exc:
            raise HdriError(f"{path}: the base64 payload does not decode ({exc}); fetch the package again") from None
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "map.exr"
        f.write_bytes(data)
        try:
            img = read_exr(f)
        except ImageFileError as exc:
            reason = str(exc).split(": ", 1)[-1].splitlines()[0]
            raise HdriError(f"{path}: the embedded EXR does not decode ({reason}); fetch the package again") from None
    if img.ndim != 3 or img.shape[2] < 3:
        raise HdriError(f"{path}: expected an RGB map, got shape {img.shape}")
    img = np.ascontiguousarray(img[..., :3], dtype=np.float32)
    if img.shape[1] != 2 * img.shape[0]:
        raise HdriError(f"{path}: {img.shape[1]}x{img.shape[0]} is not equirectangular (width must be 2 x height)")
    return img


@dataclass(frozen=True)
class RingingStats:
    """How much a decoded map rings. Energies are solid-angle-weighted luminance integrals over the sphere.

    minimum, maximum: over all channels; negative_pixels: share of pixels with a negative channel;
    negative_energy_share: ∫|min(L, 0)| / ∫|L|; clamp_power_gain: (∫max(L, 0) − ∫L) / ∫L, the light a plain clamp
    would add; blocks_ringing: 8x8 blocks holding a negative value; repair_block: the largest block size
    `repair_ringing` needs (8, 16 or 32; 0 if nothing rings); unresolved: blocks (any channel) still holding more
    negative than positive light at the largest size: negative light, not ringing (`check_ringing` refuses).
    """

    minimum: float
    maximum: float
    negative_pixels: float
    negative_energy_share: float
    clamp_power_gain: float
    blocks_ringing: int
    repair_block: int
    unresolved: int

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _blocks(img: np.ndarray, block: int) -> tuple[np.ndarray, np.ndarray]:
    """(values, weights) reshaped to (bh, block, bw, block, C) and (bh, block, bw, block, 1); edges zero-padded."""
    H, W, C = img.shape
    ph, pw = -H % block, -W % block
    v = np.pad(img.astype(np.float64), ((0, ph), (0, pw), (0, 0)))
    w = np.pad(np.broadcast_to(sh.pixel_solid_angles(H, W)[..., None], (H, W, 1)), ((0, ph), (0, pw), (0, 0)))
    shape = ((H + ph) // block, block, (W + pw) // block, block)
    return v.reshape(*shape, C), w.reshape(*shape, 1)


def _repair(img: np.ndarray) -> tuple[np.ndarray, int, int]:
    """(repaired float32 map, largest block size used, blocks left with net negative light)."""
    out = np.asarray(img, dtype=np.float32)
    H, W, C = out.shape
    used, unresolved = 0, 0
    for block in REPAIR_BLOCKS:
        v, w = _blocks(out, block)
        has_neg = (v < 0).any(axis=(1, 3), keepdims=True)
        if not has_neg.any():
            break
        used = block
        signed = (v * w).sum(axis=(1, 3), keepdims=True)
        positive = (np.maximum(v, 0.0) * w).sum(axis=(1, 3), keepdims=True)
        fixable = has_neg & (signed > 0)
        factor = np.where(fixable, signed / np.where(positive > 0, positive, 1.0), 1.0)
        fixed = np.where(fixable, np.maximum(v, 0.0) * factor, v)  # float32 -> float64 -> float32: exact elsewhere
        out = np.ascontiguousarray(fixed.reshape(v.shape[0] * block, v.shape[2] * block, C)[:H, :W],
                                   dtype=np.float32)
        unresolved = int((has_neg & ~fixable).any(axis=(1, 3, 4)).sum())
    if unresolved:
        out = np.maximum(out, np.float32(0.0))
    return out, used, unresolved


def measure_ringing(img: np.ndarray) -> RingingStats:
    """`RingingStats` of a decoded (H, W, 3) map (finite values)."""
    L = np.asarray(img, dtype=np.float64)
    H, W, _ = L.shape
    om = sh.pixel_solid_angles(H, W)
    lum = luminance(L).astype(np.float64)
    total = float(np.sum(lum * om))
    absolute = float(np.sum(np.abs(lum) * om))
    clamped = float(np.sum(luminance(np.maximum(L, 0.0)).astype(np.float64) * om))
    neg_px = (L < 0).any(axis=-1)
    b = RING_BLOCK
    ringing = np.pad(neg_px, ((0, -H % b), (0, -W % b))).reshape((H - 1) // b + 1, b, (W - 1) // b + 1, b)
    _, used, unresolved = _repair(L)
    return RingingStats(
        minimum=float(L.min()), maximum=float(L.max()), negative_pixels=float(neg_px.mean()),
        negative_energy_share=float(np.sum(np.maximum(-lum, 0.0) * om) / absolute) if absolute > 0 else 0.0,
        clamp_power_gain=(clamped - total) / total if total > 0 else float("inf"),
        blocks_ringing=int(ringing.any(axis=(1, 3)).sum()), repair_block=used, unresolved=unresolved)


def check_ringing(img: np.ndarray, path: str | Path) -> RingingStats:
    """Measure, and raise HdriError (one line naming `path`) for non-finite values, negative light beyond
    compression ringing (`RingingStats.unresolved`), or a map whose total light is not > 0."""
    L = np.asarray(img)
    if not np.all(np.isfinite(L)):
        bad = int(np.count_nonzero(~np.isfinite(L)))
        raise HdriError(f"{path}: {bad} NaN/Inf values (half floats overflow above 65504); the map cannot be used")
    stats = measure_ringing(L)
    if stats.unresolved:
        big = REPAIR_BLOCKS[-1]
        raise HdriError(f"{path}: {stats.unresolved} {big}x{big} blocks hold more negative than positive light "
                        f"(minimum {stats.minimum:.4g}): beyond compression ringing; the map cannot be used")
    if not np.isfinite(stats.clamp_power_gain):
        raise HdriError(f"{path}: the map's total light is not positive; the map cannot be used")
    return stats


def repair_ringing(img: np.ndarray) -> np.ndarray:
    """Non-negative float32 map keeping the light of every block that rings.

    For block sizes 8, 16, 32 in turn, each block (per channel) that still holds a negative value and whose
    solid-angle-weighted integral is positive gets its negatives set to 0 and its positive pixels scaled by
    signed / positive integral, so the block's light is unchanged. Blocks that never held a negative are
    unchanged bit for bit. Blocks still net-negative at 32 (refused by `check_ringing`) are clamped.
    """
    return _repair(img)[0]
