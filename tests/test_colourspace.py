"""Colour conventions: the sRGB curve against colour-science, display space, quantisation, CIELAB and the skin's
Individual Typology Angle."""
from __future__ import annotations

import numpy as np
import pytest

from rh_common.colourspace import REC709_LUMINANCE, cct_to_linear_srgb, ita_category, ita_degrees, linear_srgb_to_lab, linear_srgb_to_cct, quantize8, srgb_decode, srgb_encode, srgb_encode_reference, to_display


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


def _lab_by_hand(rgb: np.ndarray) -> np.ndarray:
    """CIELAB written out from the standards (IEC 61966-2-1 matrix, D65 white, CIE 1976 f) as an independent check."""
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
    xyz = m @ rgb / (m @ np.ones(3))  # normalised by the white point of the same matrix
    d = 6.0 / 29.0
    f = np.where(xyz > d**3, np.cbrt(xyz), xyz / (3 * d * d) + 4.0 / 29.0)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def test_lab_known_values():
    np.testing.assert_allclose(linear_srgb_to_lab(np.ones(3)), [100.0, 0.0, 0.0], atol=0.01)  # xy white point vs matrix: 0.008
    np.testing.assert_allclose(linear_srgb_to_lab(np.zeros(3)), [0.0, 0.0, 0.0], atol=1e-9)
    for srgb8 in ([194, 150, 130], [115, 82, 68], [70, 50, 43], [214, 172, 150]):  # the skin anchors (recipe.py)
        lin = srgb_decode(np.array(srgb8) / 255.0).astype(np.float64)
        np.testing.assert_allclose(linear_srgb_to_lab(lin), _lab_by_hand(lin), atol=0.05)
    # ColorChecker "light skin" from its sRGB: L* 65.7, b* 16.9 (D65) -> ITA = atan(15.7 / 16.9) = 42.9 degrees.
    lin = srgb_decode(np.array([194, 150, 130]) / 255.0)
    assert linear_srgb_to_lab(lin)[0] == pytest.approx(65.67, abs=0.02)
    assert ita_degrees(lin) == pytest.approx(np.degrees(np.arctan(15.666 / 16.900)), abs=0.05)


def test_ita_is_the_angle_of_l_and_b():
    # Constructed colours: a Lab triple with L* = 50 + b* tan(theta) has ITA theta (inverse through colour-science).
    import colour

    wp = colour.RGB_COLOURSPACES["sRGB"].whitepoint
    for theta in (60.0, 45.0, 30.0, 0.0, -20.0, -45.0):
        b = 12.0
        lab = np.array([50.0 + b * np.tan(np.radians(theta)), 8.0, b])
        rgb = colour.XYZ_to_RGB(colour.Lab_to_XYZ(lab, wp), "sRGB", chromatic_adaptation_transform=None)
        assert ita_degrees(rgb) == pytest.approx(theta, abs=0.01)  # matrix round trip: ~2e-3 degrees
    assert ita_degrees(np.ones((4, 2, 3))).shape == (4, 2)


@pytest.mark.parametrize("angle,name", [(70, "very light"), (55.01, "very light"), (55, "light"), (41.5, "light"),
                                        (30, "intermediate"), (28, "tan"), (12, "tan"), (0, "brown"), (-29.9, "brown"),
                                        (-30, "dark"), (-60, "dark")])
def test_ita_categories(angle, name):
    assert ita_category(angle) == name


def test_ita_refuses_bad_input():
    with pytest.raises(ValueError, match="finite"):
        ita_category(float("nan"))
    with pytest.raises(ValueError, match="linear_srgb_to_lab"):
        linear_srgb_to_lab(np.array([np.nan, 0.0, 0.0]))
