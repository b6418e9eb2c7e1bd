"""Procedural environments (studio, window, outdoor) and light mixtures: determinism, validity, JSON round trip,
SH agreement with brute-force irradiance, errors. The rendered diffuse-sphere check is in test_render_hdri.py."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rh_common import sh
from rh_common.imageio import write_exr
from rh_dataset import lights as L
from rh_dataset.lights import procedural

SEEDS = (0, 1, 2)


def _fresh_map(kind: str, params: dict) -> np.ndarray:
    procedural._map_cached.cache_clear()  # recompute, so equality is of two computations, not one cache entry
    return procedural.procedural_map(kind, params)


@pytest.mark.parametrize("kind", L.PROCEDURAL_KINDS)
def test_same_seed_same_bits(kind: str) -> None:
    a = L.sample_params(kind, np.random.default_rng(3))
    b = L.sample_params(kind, np.random.default_rng(3))
    assert json.dumps(a) == json.dumps(b)
    assert _fresh_map(kind, a).tobytes() == _fresh_map(kind, b).tobytes()
    assert json.dumps(L.sample_params(kind, np.random.default_rng(4))) != json.dumps(a)


@pytest.mark.parametrize("kind", L.PROCEDURAL_KINDS)
def test_maps_are_finite_non_negative_and_lit(kind: str) -> None:
    for seed in SEEDS:
        params = L.sample_params(kind, np.random.default_rng(seed))
        json.dumps(params)  # JSON-ready: plain numbers and lists only
        m = L.procedural_map(kind, params, height=64)
        assert m.shape == (64, 128, 3) and m.dtype == np.float32 and not m.flags.writeable
        assert np.all(np.isfinite(m)) and m.min() >= 0.0
        assert m.max() > 10 * np.median(m)  # bright sources on a dim surround, not a uniform grey


def test_studio_lights_have_their_roles_and_colours() -> None:
    for seed in range(8):
        p = L.sample_params("studio", np.random.default_rng(seed))
        roles = [lt["role"] for lt in p["lights"]]
        assert roles[0] == "key" and 1 <= len(roles) <= 4 and len(set(roles)) == len(roles)
        assert all(2700.0 <= lt["cct_k"] <= 7500.0 and max(lt["gel"]) == pytest.approx(1.0) for lt in p["lights"])
    # One warm (2700 K) softbox facing +X on black: the map's colour there is that black body's, its luminance 1.
    lt = {"role": "key", "shape": "softbox", "azimuth_deg": 0.0, "elevation_deg": 0.0, "width_deg": 40.0,
          "height_deg": 40.0, "cct_k": 2700.0, "gel": [1.0, 1.0, 1.0], "intensity": 1.0}
    m = L.procedural_map("studio", {"room_level": 0.0, "room_cct_k": 5000.0, "floor_factor": 1.0, "lights": [lt]},
                         height=64)
    from rh_common.colourspace import cct_to_linear_srgb
    centre = m[31:33, 63:65].mean(axis=(0, 1))  # direction +X: u = 0.5 → column W/2, the equator rows
    np.testing.assert_allclose(centre, cct_to_linear_srgb(2700.0), rtol=1e-6)
    assert m[:, :20].max() == 0.0  # nothing behind


def test_outdoor_ground_reflects_the_sky() -> None:
    p = {"sun_azimuth_deg": 40.0, "sun_elevation_deg": 35.0, "turbidity": 3.0, "ground_albedo": [0.2, 0.2, 0.2]}
    H = 64
    m = L.procedural_map("outdoor", p, height=H).astype(np.float64)
    dirs = sh.equirect_directions(H, 2 * H)
    up = dirs[..., 2] > 0
    e_h = np.einsum("hwc,hw->c", m * up[..., None], np.maximum(dirs[..., 2], 0) * sh.pixel_solid_angles(H, 2 * H))
    ground = m[~up]
    np.testing.assert_allclose(ground, np.broadcast_to(0.2 * e_h / math.pi, ground.shape), rtol=1e-6)
    sky = L.bake_sunsky(40.0, 35.0, 3.0, height=H)
    np.testing.assert_array_equal(m[up], sky[up])  # above the horizon it is Mitsuba's sunsky, as baked


@pytest.mark.parametrize("kind", L.PROCEDURAL_KINDS)
def test_sh_irradiance_matches_brute_force_within_theory(kind: str) -> None:
    # As for the bundled maps (test_lights.py): order-2 SH vs the cosine convolution, within the rigorous bound.
    normals = sh.fibonacci_sphere(300)
    for seed in SEEDS:
        m = L.procedural_map(kind, L.sample_params(kind, np.random.default_rng(seed)), height=64)
        te = L.sh_truncation_error(m, normals)
        assert np.all(te.relative <= te.bound) and te.relative_to_mean.max() <= 3.0 / 8.0, (kind, seed)


@pytest.mark.parametrize("kind", L.PROCEDURAL_KINDS)
def test_frame_json_round_trip_rebuilds_the_same_light(kind: str) -> None:
    params = L.sample_params(kind, np.random.default_rng(5))
    spec = L.LightSpec(kind, kind, "", 33.0, 0.7, params=params)
    light = L.build_light(spec)
    back = L.LightSpec.from_json(json.loads(json.dumps(spec.as_dict())), "frame.json")
    again = L.build_light(back)
    assert back == spec
    assert again.radiance.tobytes() == light.radiance.tobytes()
    np.testing.assert_array_equal(again.sh_world, light.sh_world)
    expected = sh.rotate(sh.project_equirect(light.radiance), L.rotation_z(33.0))
    np.testing.assert_allclose(light.sh_world, expected, rtol=1e-12)  # the SH of the one SH module


def test_envmap_frame_json_has_no_params_key() -> None:
    # Frames of protocols a and b keep their bytes: no new key in their light block.
    d = L.LightSpec("envmap", "city", "/x/city.exr", 1.0, 1.0).as_dict()
    assert "params" not in d and list(d) == ["kind", "name", "source", "rotation_deg", "scale", "sun_azimuth_deg",
                                             "sun_elevation_deg", "turbidity"]


def test_unknown_kind_and_bad_params_are_one_line_errors() -> None:
    with pytest.raises(ValueError) as info:
        L.LightSpec.from_json({"kind": "disco", "name": "x", "source": "", "rotation_deg": 0.0, "scale": 1.0},
                              "/data/subject_0000/test/frame_000001.json")
    msg = str(info.value)
    assert "/data/subject_0000/test/frame_000001.json" in msg and "'disco'" in msg and "\n" not in msg
    with pytest.raises(ValueError, match="unknown procedural light kind 'disco'"):
        L.sample_params("disco", np.random.default_rng(0))
    p = L.sample_params("studio", np.random.default_rng(0))
    p["lights"][0]["cct_k"] = 100.0
    with pytest.raises(ValueError, match=r"lights\[0\].cct_k"):
        L.LightSpec("studio", "studio", "", 0.0, 1.0, params=p)
    with pytest.raises(ValueError, match="params must be None"):
        L.LightSpec("envmap", "city", "/x/city.exr", 0.0, 1.0, params={})
    with pytest.raises(ValueError, match="exactly the keys"):
        L.LightSpec("window", "window", "", 0.0, 1.0, params={"room_level": 0.1})


# ------------------------------------------------------------------------------------------------ mixtures
@pytest.fixture()
def library(tmp_path: Path) -> dict[str, Path]:
    rng = np.random.default_rng(1)
    for k in range(3):
        write_exr(tmp_path / f"m{k}.exr", (rng.random((16, 32, 3)) + 0.1).astype(np.float32))
    return L.hdri_library(tmp_path)


def test_mixture_draw_order_and_determinism(library: dict[str, Path]) -> None:
    mixture = {"real": 0.85, "window": 0.15}
    for seed in range(12):
        spec = L.sample_light(np.random.default_rng(seed), library, allow_sunsky=False, mixture=mixture)
        assert spec == L.sample_light(np.random.default_rng(seed), library, allow_sunsky=False, mixture=mixture)
        twin = np.random.default_rng(seed)
        u, rotation = twin.random(), twin.uniform(0.0, 360.0)  # documented order: kind, rotation, ev, the rest
        assert spec.kind == ("envmap" if u < 0.85 else "window") and spec.rotation_deg == rotation
        if spec.kind == "envmap":
            twin.uniform(-0.5, 0.5)
            assert spec.name == sorted(library)[int(twin.integers(3))]
    assert L.check_mixture({"studio": 1, "real": 3}) == {"real": 0.75, "studio": 0.25}


@pytest.mark.parametrize("bad, match", [({"real": 1, "disco": 1}, "unknown kind 'disco'"), ({"real": -1}, "weight"),
                                        ({"real": 0}, "sum to 0"), ({}, "non-empty")])
def test_bad_mixture_rejected(bad: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        L.check_mixture(bad)


def test_export_bakes_a_procedural_frame_light(tmp_path: Path) -> None:
    # rh-export rebuilds a frame's light from its JSON alone: a procedural light needs no file.
    from rh_dataset.export.rh_light import bake_frame_light

    spec = L.LightSpec("window", "window", "", 12.0, 0.5, params=L.sample_params("window", np.random.default_rng(1)))
    meta = {"light": {**json.loads(json.dumps(spec.as_dict())), "sh_world": [[0.0] * 3] * 9},
            "camera": {"camera_to_world": np.eye(4).tolist()}, "exposure": 1.0}
    rec = bake_frame_light(meta, None, tmp_path, {}, "frame_000000.json")
    assert (tmp_path / "hdri" / rec["file"]).is_file() and rec["file"].startswith("rh_window_")
    bad = {**meta, "light": {**meta["light"], "kind": "disco"}}
    with pytest.raises(ValueError, match="frame_000000.json: light: .*'disco'"):
        bake_frame_light(bad, None, tmp_path, {}, "frame_000000.json")
