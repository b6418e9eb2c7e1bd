"""Colour conventions: the sRGB curve against colour-science, display space, quantisation."""
from __future__ import annotations

import numpy as np
import pytest

from rh_common.colourspace import REC709_LUMINANCE, cct_to_linear_srgb, linear_srgb_to_cct, quantize8, srgb_decode, srgb_encode, srgb_encode_reference, to_display


def test_fast_srgb_curve_matches_colour_science():
    x = np.concatenate([np.linspace(0, 1, 100001), [0.0031308, 0.0031309, 1e-9]]).astype(np.float32)
    np.testing.assert_allclose(srgb_encode(x), srgb_encode_reference(x), atol=1e-6)


def test_round_trip_and_known_values():
    x = np.linspace(0, 1, 1001, dtype=np.float32)
    np.testing.assert_allclose(srgb_decode(srgb_encode(x)), x, atol=2e-6)
    assert srgb_encode(np.float32(0.5)) == pytest.approx(0.735357, abs=1e-6)  # IEC 61966-2-1 curve at 0.5


def test_display_space_clips_and_refuses_non_finite():
    hdr = np.array([[[1e5, 0.0, 0.25]]], np.float32)
    d = to_display(hdr, 2.0)
    np.testing.assert_allclose(d[0, 0], [1.0, 0.0, srgb_encode(np.float32(0.5))], atol=1e-7)
    with pytest.raises(ValueError, match="NaN"):
        to_display(np.array([np.nan], np.float32), 1.0)
    with pytest.raises(ValueError, match="exposure"):
        to_display(hdr, 0.0)


def test_quantize8_rounds_half_up():
    assert quantize8(np.array([0.0, 0.5 / 255, 1.0, 2.0, -1.0])).tolist() == [0, 1, 255, 255, 0]


def test_colour_temperature_white_point_luminance_and_order():
    # The Planckian locus at 6504 K passes within ~0.003 in xy of D65, i.e. a few percent of sRGB white.
    np.testing.assert_allclose(cct_to_linear_srgb(6504.0), [1.0, 1.0, 1.0], atol=0.05)
    cols = [cct_to_linear_srgb(t) for t in (1800.0, 2700.0, 4000.0, 6504.0, 10000.0, 20000.0)]
    for c in cols:
        assert c.min() >= 0 and float(c @ REC709_LUMINANCE) == pytest.approx(1.0, rel=1e-12)
    ratio = [c[2] / max(c[0], 1e-12) for c in cols]
    assert ratio == sorted(ratio)  # hotter is bluer
    with pytest.raises(ValueError, match="1667, 25000"):
        cct_to_linear_srgb(1000.0)


def test_colour_temperature_round_trip():
    for t in (2856.0, 4000.0, 5000.0, 6504.0):  # McCamy's fit is good to a few kelvin here
        assert linear_srgb_to_cct(cct_to_linear_srgb(t)) == pytest.approx(t, abs=30)
    assert np.isnan(linear_srgb_to_cct(np.zeros(3)))
