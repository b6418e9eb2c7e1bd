"""rh_dataset.lights: specs, HDRI loading, sampling, SH of the light, and agreement with Mitsuba's envmap."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rh_common import sh
from rh_common.imageio import write_exr
from rh_dataset import lights as L
from rh_dataset.lights.mitsuba_env import eval_emitter

RNG_SEED = 7


def _bundled() -> dict[str, Path]:
    # setup.sh installs the maps: their absence is a failure, never a skip.
    return L.bundled_hdris()


@pytest.fixture(scope="module")
def mi():
    import mitsuba
    if mitsuba.variant() is None:
        mitsuba.set_variant("llvm_ad_rgb")
    return mitsuba


def _light(radiance: np.ndarray, rotation_deg: float) -> L.Light:
    spec = L.LightSpec("envmap", "test", "/nonexistent/test.exr", rotation_deg, 1.0)
    r = np.ascontiguousarray(radiance, dtype=np.float32)
    return L.Light(spec, r, sh.rotate(sh.project_equirect(r), L.rotation_z(rotation_deg)), 0)


# ------------------------------------------------------------------------------------------------ spec
GOOD_ENV = dict(kind="envmap", name="city", source="/x/city.exr", rotation_deg=10.0, scale=1.0)
GOOD_SKY = dict(kind="sunsky", name="sunsky", source="", rotation_deg=0.0, scale=1.0, sun_azimuth_deg=30.0,
                sun_elevation_deg=40.0, turbidity=3.0)


@pytest.mark.parametrize(
    "base, field, value",
    [
        (GOOD_ENV, "kind", "area"),
        (GOOD_ENV, "name", ""),
        (GOOD_ENV, "source", ""),
        (GOOD_ENV, "rotation_deg", float("nan")),
        (GOOD_ENV, "scale", 0.0),
        (GOOD_ENV, "scale", float("inf")),
        (GOOD_ENV, "turbidity", 3.0),
        (GOOD_SKY, "source", "/x/sky.exr"),
        (GOOD_SKY, "sun_elevation_deg", 95.0),
        (GOOD_SKY, "sun_azimuth_deg", None),
        (GOOD_SKY, "turbidity", 0.5),
    ],
)
def test_lightspec_validation_names_the_field(base: dict, field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        L.LightSpec(**{**base, field: value})


def test_lightspec_valid_and_frozen() -> None:
    spec = L.LightSpec(**GOOD_SKY)
    assert spec.as_dict()["turbidity"] == 3.0
    with pytest.raises(AttributeError):
        spec.scale = 2.0  # type: ignore[misc]


# ------------------------------------------------------------------------------------------------ loading
def test_load_hdri_clamps_and_counts_negatives(tmp_path: Path) -> None:
    img = np.full((8, 16, 3), 0.5, np.float32)
    img[1, 2, 0] = -0.01
    img[3, 4, :] = -1e-4
    write_exr(tmp_path / "neg.exr", img)
    out, clamped = L.load_hdri(tmp_path / "neg.exr")
    assert clamped == 4
    assert out.dtype == np.float32 and out.shape == (8, 16, 3) and out.min() == 0.0
    assert not out.flags.writeable


def test_load_hdri_drops_alpha_and_reads_hdr(tmp_path: Path, mi) -> None:
    rgba = np.random.default_rng(RNG_SEED).random((8, 16, 4)).astype(np.float32)
    write_exr(tmp_path / "a.exr", rgba)
    np.testing.assert_array_equal(L.load_hdri(tmp_path / "a.exr")[0], rgba[..., :3])
    rgb = rgba[..., :3] * 10
    mi.Bitmap(np.ascontiguousarray(rgb)).write(str(tmp_path / "b.hdr"))
    got, _ = L.load_hdri(tmp_path / "b.hdr")
    # RGBE: 8-bit mantissas sharing the largest channel's exponent → error ≤ (pixel max) / 128.
    assert np.all(np.abs(got - rgb) <= rgb.max(axis=-1, keepdims=True) / 64)
    assert sorted(L.hdri_library(tmp_path)) == ["a", "b"]


@pytest.mark.parametrize(
    "name, content, fix",
    [
        ("garbage.exr", b"not an exr at all", "float32 RGB EXR"),
        ("garbage.hdr", b"nope", "float32 EXR"),
        ("missing.exr", None, "check the path"),
    ],
)
def test_unreadable_hdri_error_names_file_and_fix(tmp_path: Path, name: str, content: bytes | None,
                                                  fix: str) -> None:
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(ValueError) as info:
        L.load_hdri(path)
    msg = str(info.value)
    assert str(path) in msg and fix in msg and "\n" not in msg


def test_wrong_shape_and_non_finite_hdri_rejected(tmp_path: Path) -> None:
    write_exr(tmp_path / "square.exr", np.ones((8, 8, 3), np.float32))
    with pytest.raises(ValueError, match="square.exr.*equirectangular"):
        L.load_hdri(tmp_path / "square.exr")
    img = np.ones((8, 16, 3), np.float32)
    img[2, 2, 1] = np.inf
    write_exr(tmp_path / "inf.exr", img)
    with pytest.raises(ValueError, match="inf.exr.*NaN/Inf"):
        L.load_hdri(tmp_path / "inf.exr")
    write_exr(tmp_path / "grey.exr", np.ones((8, 16), np.float32))
    with pytest.raises(ValueError, match="grey.exr.*RGB"):
        L.load_hdri(tmp_path / "grey.exr")


def test_library_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="no .exr or .hdr"):
        L.hdri_library(tmp_path)
    with pytest.raises(FileNotFoundError):
        L.hdri_library(tmp_path / "nope")


def test_bundled_hdris_found() -> None:
    lib = _bundled()
    assert {"city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"} <= set(lib)


# ------------------------------------------------------------------------------------------------ scale, sampling
def test_normalised_scale_gives_unit_mean_luminance() -> None:
    H, W = 16, 32
    img = np.zeros((H, W, 3), np.float32)
    img[: H // 2] = [2.0, 2.0, 2.0]  # upper hemisphere luminance 2, lower 0 → mean 1
    assert L.normalised_scale(img) == pytest.approx(1.0, rel=1e-6)
    rng_img = np.random.default_rng(RNG_SEED).random((H, W, 3)).astype(np.float32) * 5
    s = L.normalised_scale(rng_img)
    lum = (rng_img * s) @ np.array([0.2126, 0.7152, 0.0722])
    assert np.sum(lum * sh.pixel_solid_angles(H, W)) / (4 * math.pi) == pytest.approx(1.0, rel=1e-5)
    with pytest.raises(ValueError):
        L.normalised_scale(np.zeros((4, 8, 3)))


@pytest.fixture()
def small_library(tmp_path: Path) -> dict[str, Path]:
    rng = np.random.default_rng(RNG_SEED)
    for k in range(3):
        write_exr(tmp_path / f"map{k}.exr", (rng.random((16, 32, 3)) * (k + 1)).astype(np.float32))
    return L.hdri_library(tmp_path)


def test_sample_light_is_deterministic_and_in_range(small_library: dict[str, Path]) -> None:
    specs = [L.sample_light(np.random.default_rng(5), small_library, allow_sunsky=False) for _ in range(2)]
    assert specs[0] == specs[1]
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(20):
        spec = L.sample_light(rng, small_library, exposure_ev_range=(-0.5, 0.5), allow_sunsky=False)
        assert spec.kind == "envmap" and spec.name in small_library and 0 <= spec.rotation_deg < 360
        base = L.normalised_scale(L.load_hdri(spec.source)[0])
        assert 2**-0.5 * base * (1 - 1e-9) <= spec.scale <= 2**0.5 * base * (1 + 1e-9)


def test_sample_light_sunsky() -> None:
    spec = L.sample_light(np.random.default_rng(RNG_SEED), {}, allow_sunsky=True)
    assert spec.kind == "sunsky" and spec.source == ""
    lo, hi = L.SUNSKY_ELEVATION_RANGE_DEG
    assert lo <= spec.sun_elevation_deg <= hi
    with pytest.raises(ValueError):
        L.sample_light(np.random.default_rng(0), {}, allow_sunsky=False)


def test_build_light_envmap(small_library: dict[str, Path], tmp_path: Path) -> None:
    img = np.ones((16, 32, 3), np.float32)
    img[0, 0, 0] = -0.5
    write_exr(tmp_path / "n.exr", img)
    spec = L.LightSpec("envmap", "n", str(tmp_path / "n.exr"), 37.0, 2.0)
    light = L.build_light(spec)
    assert light.negative_pixels_clamped == 1
    assert light.radiance.dtype == np.float32 and light.radiance[5, 5, 0] == 2.0 and light.radiance[0, 0, 0] == 0
    expected = sh.rotate(sh.project_equirect(light.radiance), L.rotation_z(37.0))
    np.testing.assert_allclose(light.sh_world, expected, rtol=1e-12)
    assert light.sh_world.shape == (9, 3) and not light.sh_world.flags.writeable


# ------------------------------------------------------------------------------------------------ Mitsuba agreement
@pytest.mark.parametrize("rotation_deg", [0.0, 90.0, 33.3])
def test_mitsuba_envmap_matches_our_mapping(mi, rotation_deg: float) -> None:
    """Mitsuba's envmap, as built by mitsuba_emitter_dict, returns our (rotated) pixel values at our pixel centres.

    This pins the direction of every pixel (ARCHITECTURE.md mapping), the sign of the rotation and the
    (2H+1)-row layout that compensates Mitsuba's pole-anchored rows."""
    H, W = 16, 32
    rng = np.random.default_rng(RNG_SEED)
    img = rng.random((H, W, 3)).astype(np.float32)
    j, i = 4, 7
    img[j, i] = [50.0, 60.0, 70.0]  # a bright patch at a known pixel
    light = _light(img, rotation_deg)
    emitter = mi.load_dict(L.mitsuba_emitter_dict(light))
    dirs = sh.equirect_directions(H, W)
    got = eval_emitter(mi, emitter, dirs.reshape(-1, 3)).reshape(H, W, 3)
    world = light.world_radiance()
    np.testing.assert_allclose(got, world, atol=1e-4 * 70)  # float32 atan2/acos in Mitsuba's lookup
    # The patch: looking along Rz · (direction of pixel (j, i)) Mitsuba returns the patch value.
    d = L.rotation_z(rotation_deg) @ dirs[j, i]
    np.testing.assert_allclose(eval_emitter(mi, emitter, d[None])[0], [50, 60, 70], rtol=1e-4)
    if rotation_deg == 90.0:  # a whole number of pixels: the patch moved W/4 columns to the left
        assert np.unravel_index(np.argmax(got[..., 0]), (H, W)) == (j, (i - W // 4) % W)


def test_traversable_data_layout(mi) -> None:
    # Swapping maps through mi.traverse needs Mitsuba's padded layout; a swapped map must render like a new one.
    rng = np.random.default_rng(RNG_SEED)
    a, b = (rng.random((8, 16, 3)).astype(np.float32) for _ in range(2))
    emitter = mi.load_dict(L.mitsuba_emitter_dict(_light(a, 10.0)))
    params = mi.traverse(emitter)
    np.testing.assert_array_equal(np.array(params["data"]), L.mitsuba_envmap_data(a))
    params["data"] = mi.TensorXf(L.mitsuba_envmap_data(b))
    params.update()
    dirs = sh.equirect_directions(8, 16).reshape(-1, 3)
    fresh = mi.load_dict(L.mitsuba_emitter_dict(_light(b, 10.0)))
    np.testing.assert_allclose(eval_emitter(mi, emitter, dirs), eval_emitter(mi, fresh, dirs), atol=1e-6)


def test_sh_is_of_what_mitsuba_renders(mi) -> None:
    # Project Mitsuba's own lookups on an 8x finer grid and compare with sh_world. The residual is Mitsuba's
    # bilinear interpolation vs our piecewise-constant cells: O(h²) with h = π/H.
    H, W = 32, 64
    light = _light(np.random.default_rng(RNG_SEED).random((H, W, 3)) * 2, 25.0)
    emitter = mi.load_dict(L.mitsuba_emitter_dict(light))
    f = 8
    fine = eval_emitter(mi, emitter, sh.equirect_directions(H * f, W * f).reshape(-1, 3)).reshape(H * f, W * f, 3)
    err = np.abs(sh.project_equirect(fine) - light.sh_world).max()
    assert err < 0.1 * (math.pi / H) ** 2 * np.abs(light.sh_world).max()


def test_rotate_equirect_consistent_with_sh_rotate() -> None:
    H = 64
    img = np.random.default_rng(RNG_SEED).random((H, 2 * H, 3)).astype(np.float32)
    c = sh.project_equirect(img)
    for deg in (90.0, -45.0, 360.0):  # whole pixels: exact
        np.testing.assert_allclose(sh.project_equirect(L.rotate_equirect(img, deg)),
                                   sh.rotate(c, L.rotation_z(deg)), atol=1e-5)
    # Fractional: linear interpolation in u, O(h²) in the coefficients.
    np.testing.assert_allclose(sh.project_equirect(L.rotate_equirect(img, 12.34)), sh.rotate(c, L.rotation_z(12.34)),
                               atol=(math.pi / H) ** 2 * np.abs(c).max())


# ------------------------------------------------------------------------------------------------ sunsky
def test_sunsky_bake(mi) -> None:
    az, el = 30.0, 40.0
    m = L.bake_sunsky(az, el, 3.0, height=64)
    assert m.shape == (64, 128, 3) and np.all(np.isfinite(m)) and m.min() >= 0
    assert m[32:].max() == 0.0  # no light below the horizon (Mitsuba's sunsky has no ground)
    # The sun is the brightest pixel, in the pixel containing the sun direction.
    j, i = np.unravel_index(np.argmax(m[..., 0]), m.shape[:2])
    d = L.sun_direction(az, el)
    u = (0.5 - math.atan2(d[1], d[0]) / (2 * math.pi)) * 128
    assert (j, i) == (int(math.acos(d[2]) / math.pi * 64), int(u))
    # Its power equals the sun's radiance times the disc's solid angle (uniform disc in Mitsuba 3.9).
    emitter = mi.load_dict({"type": "sunsky", "sun_direction": d.tolist(), "turbidity": 3.0, "sky_scale": 0.0,
                            "sun_aperture": L.SUN_APERTURE_DEG})
    l_sun = eval_emitter(mi, emitter, d[None])[0]
    omega_sun = 2 * math.pi * (1 - math.cos(math.radians(L.SUN_APERTURE_DEG) / 2))
    neighbours = np.median(m[j - 1:j + 2, i - 1:i + 2].reshape(-1, 3), axis=0)
    sun_power = (m[j, i] - neighbours) * sh.pixel_solid_angles(64, 128)[j, i]
    np.testing.assert_allclose(sun_power, l_sun * omega_sun, rtol=2e-2)
    c = sh.project_equirect(m)
    assert np.all(np.isfinite(c)) and c[0].min() > 0
    spec = L.LightSpec("sunsky", "sunsky", "", 15.0, 0.5, az, el, 3.0)
    light = L.build_light(spec)
    assert np.all(np.isfinite(light.sh_world)) and light.radiance.shape == (512, 1024, 3)
    assert mi.load_dict(L.mitsuba_emitter_dict(light)) is not None


# ------------------------------------------------------------------------------------------------ SH truncation
def test_truncation_error_of_low_order_lighting_is_quadrature_only() -> None:
    H = 64
    dirs = sh.equirect_directions(H, 2 * H)
    img = np.repeat((1.0 + 0.5 * dirs[..., 2:3] + 0.3 * dirs[..., 0:1] * dirs[..., 1:2]), 3, axis=-1)
    te = L.sh_truncation_error(img, sh.fibonacci_sphere(100))
    assert te.max < (math.pi / H) ** 2  # order ≤ 2 lighting: SH is exact, only the O(h²) quadrature remains


def test_truncation_error_of_bundled_hdris_within_theory() -> None:
    """Order-2 SH irradiance vs brute-force cosine convolution for every bundled HDRI (64x32) and a sunsky.

    Bounds (both rigorous for L ≥ 0): the order-2 clamped-cosine kernel K₂(t) = 1/4 + t/2 + (5/32)(3t² − 1)
    differs from max(0, t) by at most 3/32 (at t = 0), so |E₂(n) − E(n)| ≤ (3/32) ∫L dω per normal, and since
    the mean of E over normals is ∫L dω / 4, the error is at most 3/8 = 37.5% of the mean irradiance.
    """
    lib = _bundled()
    normals = sh.fibonacci_sphere(300)
    maps = {name: L.downsample_equirect(L.load_hdri(p)[0], 16) for name, p in lib.items()}
    maps["sunsky"] = L.downsample_equirect(L.bake_sunsky(30.0, 40.0, 3.0), 16)
    for name, radiance in maps.items():
        te = L.sh_truncation_error(radiance, normals)
        print(f"{name:10s} mean {100 * te.mean:6.2f}%  p95 {100 * te.p95:6.2f}%  max {100 * te.max:8.2f}%  "
              f"max/meanE {100 * te.relative_to_mean.max():5.2f}%")
        assert np.all(te.relative <= te.bound), name
        assert te.relative_to_mean.max() <= 3.0 / 8.0, name


@pytest.mark.slow
def test_truncation_error_full_resolution() -> None:
    lib = _bundled()
    normals = sh.fibonacci_sphere(500)
    for name, p in lib.items():
        te = L.sh_truncation_error(L.load_hdri(p)[0], normals)
        assert np.all(te.relative <= te.bound) and te.relative_to_mean.max() <= 3.0 / 8.0, name
