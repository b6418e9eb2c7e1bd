"""Colour conventions shared by every part (see docs/ARCHITECTURE.md, "Colour").

The sRGB transfer function is colour-science's IEC 61966-2-1 implementation; these wrappers fix the dtype
(float32 in, float32 out) and the display-space rule so that no module writes its own curve.
"""
from __future__ import annotations

import colour
import numpy as np

REC709_LUMINANCE = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] to sRGB-encoded values in [0, 1] (input is clipped to [0, 1] first).

    The IEC 61966-2-1 curve written out in float32: colour-science's implementation (used by
    `srgb_encode_reference`) costs ~20 ms per 512x512 image, which dominates LPIPS's own cost; a test holds the
    two within 1e-6.
    """
    x = np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    low = x * np.float32(12.92)
    high = np.float32(1.055) * np.power(np.maximum(x, np.float32(0.0031308)), np.float32(1 / 2.4)) - np.float32(0.055)
    return np.where(x <= np.float32(0.0031308), low, high).astype(np.float32)


def srgb_encode_reference(linear: np.ndarray) -> np.ndarray:
    """colour-science's sRGB encoding (float64), the reference `srgb_encode` is tested against."""
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.asarray(colour.cctf_encoding(x, function="sRGB"), dtype=np.float64)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear values in [0, 1]."""
    x = np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)
    return np.asarray(colour.cctf_decoding(x, function="sRGB"), dtype=np.float32)


def to_display(radiance: np.ndarray, exposure: float) -> np.ndarray:
    """HDR linear radiance to display space: sRGB(clip(exposure * radiance, 0, 1)), float32 in [0, 1].

    Non-finite input raises: a NaN would otherwise be clipped into a plausible-looking pixel.
    """
    radiance = np.asarray(radiance, dtype=np.float32)
    if not np.all(np.isfinite(radiance)):
        raise ValueError("to_display: radiance contains NaN or Inf")
    # Checked as the float32 it is multiplied in: 1e39 is finite in float64 but inf in float32 (0 * inf = NaN).
    if not (np.isfinite(exposure) and 0 < float(exposure) <= float(np.finfo(np.float32).max)):
        raise ValueError(f"to_display: exposure must be a positive number within float32 range, got {exposure!r}")
    return srgb_encode(radiance * np.float32(exposure))


def luminance(rgb_linear: np.ndarray) -> np.ndarray:
    """Rec.709 relative luminance of linear RGB (last axis = channels)."""
    return np.asarray(rgb_linear, dtype=np.float32)[..., :3] @ REC709_LUMINANCE


def cct_to_linear_srgb(cct_kelvin: float) -> np.ndarray:
    """Linear Rec.709 RGB (3,) float64 of a black body at `cct_kelvin`, scaled to Rec.709 luminance 1.

    colour-science's Kang et al. (2002) fit of the Planckian locus (valid 1667-25000 K) gives the chromaticity;
    XYZ -> sRGB without chromatic adaptation, so ~6500 K is near-white. The few out-of-gamut negatives (below
    ~1900 K, blue) are clipped to 0 before rescaling.
    """
    t = float(cct_kelvin)
    if not (np.isfinite(t) and 1667.0 <= t <= 25000.0):
        raise ValueError(f"cct_to_linear_srgb: colour temperature must be in [1667, 25000] K, got {cct_kelvin!r}")
    x, y = colour.CCT_to_xy(t, method="Kang 2002")
    rgb = colour.XYZ_to_RGB(colour.xyY_to_XYZ([x, y, 1.0]), "sRGB", chromatic_adaptation_transform=None)
    rgb = np.maximum(np.asarray(rgb, dtype=np.float64), 0.0)
    return rgb / float(rgb @ REC709_LUMINANCE.astype(np.float64))


def linear_srgb_to_cct(rgb_linear: np.ndarray) -> float:
    """Correlated colour temperature (K) of a linear Rec.709 colour: colour-science's McCamy (1992) fit from its
    xy chromaticity (good to a few kelvin from 2856 to 6504 K, rougher outside 2000-12500 K). NaN for black."""
    rgb = np.asarray(rgb_linear, dtype=np.float64).reshape(3)
    xyz = colour.RGB_to_XYZ(rgb, "sRGB", chromatic_adaptation_transform=None)
    if not xyz.sum() > 0:
        return float("nan")
    return float(colour.xy_to_CCT(colour.XYZ_to_xy(xyz), method="McCamy 1992"))


def linear_srgb_to_lab(rgb_linear: np.ndarray) -> np.ndarray:
    """CIE 1976 L*a*b* (..., 3) float64 of linear Rec.709 / sRGB colours, relative to the sRGB white point (D65;
    colour-science's RGB -> XYZ -> Lab, no chromatic adaptation). White (1, 1, 1) is (100, 0, 0)."""
    rgb = np.asarray(rgb_linear, dtype=np.float64)
    if rgb.shape[-1:] != (3,) or not np.all(np.isfinite(rgb)):
        raise ValueError(f"linear_srgb_to_lab: expected finite (..., 3) linear RGB, got shape {rgb.shape}")
    xyz = colour.RGB_to_XYZ(rgb, "sRGB", chromatic_adaptation_transform=None)
    return np.asarray(colour.XYZ_to_Lab(xyz, colour.RGB_COLOURSPACES["sRGB"].whitepoint), dtype=np.float64)


# Individual Typology Angle categories of skin (Chardon, Cretois & Hourseau 1991; Del Bino et al. 2006): lower
# bound in degrees of each, lightest first; below the last bound is "dark".
ITA_CATEGORIES = (("very light", 55.0), ("light", 41.0), ("intermediate", 28.0), ("tan", 10.0), ("brown", -30.0),
                  ("dark", -np.inf))


def ita_degrees(rgb_linear: np.ndarray) -> np.ndarray:
    """Individual Typology Angle of linear sRGB skin colours: atan((L* - 50) / b*) in degrees (..., ) float64.

    Written as atan2(L* - 50, b*), which equals the arctangent for b* > 0 (every skin colour is yellowish) and stays
    defined at b* = 0; a colour with b* <= 0 is not a skin colour and its angle (>= 90 or <= -90) says so."""
    lab = linear_srgb_to_lab(rgb_linear)
    return np.degrees(np.arctan2(lab[..., 0] - 50.0, lab[..., 2]))


def ita_category(ita: float) -> str:
    """The ITA category of an angle in degrees: very light > 55 >= light > 41 >= intermediate > 28 >= tan > 10 >=
    brown > -30 >= dark."""
    a = float(ita)
    if not np.isfinite(a):
        raise ValueError(f"ita_category: the angle must be finite, got {ita!r}")
    return next(name for name, lower in ITA_CATEGORIES if a > lower)


def quantize8(x01: np.ndarray) -> np.ndarray:
    """[0, 1] floats to uint8 with round-half-up, the one quantisation rule for 8-bit files."""
    return np.floor(np.clip(np.asarray(x01, dtype=np.float64), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
