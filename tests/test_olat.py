"""One-light-at-a-time lights and the olat split: the disc map against the analytic cone (SH by zonal harmonics,
irradiance by the cosine law), the strength and frame record, the split's frame order and poses, errors.
The rendered diffuse sphere under an OLAT light is in test_render_hdri.py."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rh_common import sh
from rh_common.colourspace import luminance
from rh_dataset import lights as L
from rh_dataset.generate.frames import exposure_for, light_for, olat_light
from rh_dataset.generate.plan import DatasetPlan, pose_frame
from rh_dataset.lights import olat
from rh_dataset.lights.sunsky import sun_direction
from rh_dataset.render.scene import RenderSettings
from rh_dataset.spec import SpecError, load_protocol

CASES = [(45.0, 65.0, 3.0), (270.0, 25.0, 3.0), (10.0, -25.0, 2.0), (0.0, 88.0, 5.0), (123.4, 10.0, 0.5)]
_BAND = [0, 2, 2, 2, 6, 6, 6, 6, 6]  # the zonal (m = 0) index of each coefficient's band


def _cone_zonal(alpha: float) -> np.ndarray:
    # ∫_cone Y_l0 dω of a unit-radiance cone about +Z: 2π ∫_{cos α}^1 Y_l0(t) dt, in closed form.
    k0, k1, _, k3, _ = sh.SH_CONSTANTS
    c = math.cos(alpha)
    z = np.zeros(9)
    z[0], z[2], z[6] = 2 * math.pi * k0 * (1 - c), math.pi * k1 * (1 - c * c), 2 * math.pi * k3 * c * (1 - c * c)
    return z


def _rotation_taking_z_to(d: np.ndarray) -> np.ndarray:
    axis = np.cross([0.0, 0.0, 1.0], d)
    s, c = np.linalg.norm(axis), d[2]
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K  # Rodrigues


@pytest.mark.parametrize("az, el, radius", CASES)
def test_disc_sh_matches_the_rotated_zonal_harmonics_of_a_cone(az, el, radius):
    p = L.olat_params(az, el, radius, [0.2, 0.5, 1.0])
    m = L.olat_map(p)
    got = sh.project_equirect(m)
    z = _cone_zonal(math.radians(radius))
    d = sun_direction(az, el)
    rotated = sh.rotate(z[:, None], _rotation_taking_z_to(d))[:, 0]
    # Independently: a zonal function rotated to d has coefficients z_l Y_lm(d) / Y_l0(+Z).
    addition = z[_BAND] * sh.basis(d) / sh.basis(np.array([0.0, 0.0, 1.0]))[_BAND]
    np.testing.assert_allclose(rotated, addition, atol=1e-12 * z[0])
    for ch, c in enumerate(p["colour"]):
        np.testing.assert_allclose(got[:, ch], c * rotated, atol=3e-4 * z[0])  # measured ~1e-4: the disc's edge
    np.testing.assert_allclose(got[0], z[0] * np.array(p["colour"]), rtol=1e-6)  # the solid angle (float32 map)


@pytest.mark.parametrize("az, el, radius", CASES)
def test_irradiance_follows_the_cosine_law_of_a_small_source(az, el, radius):
    p = L.olat_params(az, el, radius)
    m = L.olat_map(p)
    d = sun_direction(az, el)
    n = sh.fibonacci_sphere(160)  # brute force costs normals x 512 x 1024: a few hundred keep it at seconds
    beta = np.arccos(np.clip(n @ d, -1.0, 1.0))
    lit = beta < math.radians(89.0 - radius)  # the whole disc above the surface's horizon
    e = L.brute_force_irradiance(m, n[lit])[:, 0]
    alpha = math.radians(radius)
    cone = math.pi * math.sin(alpha) ** 2 * np.cos(beta[lit])  # exact for a uniform cone, fully visible
    np.testing.assert_allclose(e, cone, atol=2e-4 * cone.max())  # measured <5e-5
    point = olat.solid_angle(radius) * np.cos(beta[lit])  # Lambert's law for a point source of the same power
    np.testing.assert_allclose(e, point, atol=(1 - math.cos(alpha)) / 2 * point.max() + 2e-4 * point.max())
    dark = beta > math.radians(90.0 + radius + 1.0)
    assert np.all(L.brute_force_irradiance(m, n[dark]) == 0.0)  # behind the surface: no light at all


def test_strength_record_and_exposure():
    split = load_protocol("olat_a").split("olat")
    light = olat_light(split, 5)
    rec = L.olat_record(light, "rings16", 5)
    az, el = L.olat_directions("rings16")[5]
    assert light.spec.kind == "olat" and light.spec.rotation_deg == 0.0 and light.spec.params["radius_deg"] == 3.0
    np.testing.assert_allclose(rec["direction_world"], sun_direction(az, el), atol=1e-12)
    assert rec["solid_angle_sr"] == pytest.approx(2 * math.pi * (1 - math.cos(math.radians(3.0))), rel=1e-12)
    assert luminance(np.array(rec["irradiance_facing"])) == pytest.approx(math.pi, rel=1e-5)
    np.testing.assert_allclose(rec["irradiance_facing"], rec["irradiance_facing_cone"], rtol=2e-4)
    np.testing.assert_allclose(rec["radiance"], [light.spec.scale] * 3)
    # The map rendered is the spec's: ∫L dω = radiance · Ω (float32 storage aside).
    H, W = light.radiance.shape[:2]
    power = np.einsum("hwc,hw->c", light.radiance.astype(np.float64), sh.pixel_solid_angles(H, W))
    np.testing.assert_allclose(power, np.array(rec["radiance"]) * rec["solid_angle_sr"], rtol=1e-5)
    assert exposure_for(light) == pytest.approx(1.0, rel=1e-5)  # a white surface facing it displays at 1
    back = L.LightSpec.from_json(json.loads(json.dumps({**light.spec.as_dict(), "olat": rec})), "frame.json")
    assert back == light.spec and L.build_light(back).radiance.tobytes() == light.radiance.tobytes()


def test_direction_sets_are_documented_spreads():
    for name in ("rings16", "fibonacci16"):
        dirs = np.array([sun_direction(az, el) for az, el in L.olat_directions(name)])
        assert len(dirs) == 16 and (dirs[:, 2] > 0).sum() == 12 and (dirs[:, 2] < 0).sum() == 4, name
        cos = dirs @ dirs.T - 2 * np.eye(16)
        assert np.degrees(np.arccos(cos.max())) > 20.0, name  # no two directions closer than 20 degrees
    assert (270.0, 25.0) in L.olat_directions("rings16")  # from the camera's side (frame_body: camera at -Y)


def test_olat_split_reuses_the_test_poses_direction_by_direction():
    for proto, pose_split in (("a", "test"), ("b", "train")):
        base, spec = load_protocol(proto), load_protocol(f"olat_{proto}")
        assert spec.splits[:2] == base.splits and "olat" not in json.dumps(base.to_json())  # a, b unchanged
        split = spec.split("olat")
        assert split.frames == 160 and split.olat.n_directions == 16
        assert [pose_frame(spec, split, i) for i in (0, 15, 16, 159)] == [
            (spec.split(pose_split), 0), (spec.split(pose_split), 0), (spec.split(pose_split), 1),
            (spec.split(pose_split), 9)]
        plan = DatasetPlan(out=Path("x"), spec=spec, settings=RenderSettings())
        a, b = light_for(plan, split, 0, 17, {}), light_for(plan, split, 3, 17, {})  # no draw: same for every subject
        assert a.spec == b.spec and a.spec.name == "rings16_01"
        assert a.sh_world.tobytes() == b.sh_world.tobytes()
        np.testing.assert_allclose(a.sh_world, sh.project_equirect(a.radiance), rtol=1e-12, atol=1e-12)


def _scene(tmp_path: Path, olat_block) -> str:
    data = json.loads(Path(load_protocol("olat_a").source).read_text())
    if olat_block is None:
        del data["splits"]["olat"]["olat"]
    else:
        data["splits"]["olat"]["olat"] = olat_block
    p = tmp_path / "bad_olat.json"
    p.write_text(json.dumps(data))
    return str(p)


@pytest.mark.parametrize("block, message", [
    ({"directions": "dome99"}, "unknown OLAT direction set 'dome99'; known: rings16, fibonacci16"),
    ({"directions": "rings16", "radius_deg": 0.0}, "solid angle"),
    ({"directions": "rings16", "radius_deg": -2}, "solid angle"),
    ({"directions": "rings16", "radius_deg": 45.0}, r"\[0.5, 20\]"),
    ({"directions": "rings16", "colour": [0, 0, 0]}, "colour"),
    ({"directions": "rings16", "size": 1}, "unknown key"),
    (None, "light 'olat' and an 'olat' block go together"),
])
def test_bad_olat_descriptions_are_one_line_errors_naming_the_file(tmp_path, block, message):
    path = _scene(tmp_path, block)
    with pytest.raises(SpecError, match=message) as info:
        load_protocol(path)
    assert "\n" not in str(info.value) and (block is None or path in str(info.value))


def test_bad_olat_light_params_are_one_line_errors():
    with pytest.raises(ValueError, match="unknown OLAT direction set 'x'"):
        L.olat_directions("x")
    for radius in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="solid angle") as info:
            L.olat_params(0.0, 30.0, radius)
        assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="exactly the keys"):
        L.LightSpec("olat", "o", "", 0.0, 1.0, params={"azimuth_deg": 0.0})
    with pytest.raises(ValueError, match="source must be ''"):
        L.LightSpec("olat", "o", "x.exr", 0.0, 1.0, params=L.olat_params(0.0, 30.0, 3.0))


def test_more_poses_than_the_test_split_is_refused(tmp_path):
    data = json.loads(Path(load_protocol("olat_a").source).read_text())
    data["splits"]["olat"]["frames"] = 16 * 150 + 1
    p = tmp_path / "long.json"
    p.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=r"more poses \(151\) than test has frames \(150\)"):
        load_protocol(str(p))


def test_export_bakes_an_olat_frame_light_keeping_its_power(tmp_path):
    from rh_common.imageio import read_exr
    from rh_dataset.export.rh_light import bake_frame_light

    light = olat_light(load_protocol("olat_a").split("olat"), 4)
    meta = {"light": {**json.loads(json.dumps(light.spec.as_dict())), "sh_world": [[0.0] * 3] * 9},
            "camera": {"camera_to_world": np.eye(4).tolist()}, "exposure": 1.0}
    rec = bake_frame_light(meta, None, tmp_path, {}, "frame_000004.json")
    baked = read_exr(tmp_path / "hdri" / rec["exr"]).astype(np.float64)
    # The bake resamples (bilinear, another grid): the disc's power survives to the resampling's accuracy.
    from rh_dataset.export.rh_light import ia_directions  # noqa: F401  (grid documented there)
    H, W = baked.shape[:2]
    lat = (np.arange(H) / (H - 1) - 0.5) * math.pi
    dA = np.cos(lat)[:, None] * (math.pi / (H - 1)) * (2 * math.pi / (W - 1))
    power = luminance(np.einsum("hwc,hw->c", baked, np.broadcast_to(dA, (H, W))))
    assert power == pytest.approx(light.spec.scale * olat.solid_angle(3.0), rel=0.03)


def test_olat_frames_pose_the_body_as_the_test_split_does():
    from rh_dataset.generate.subjects import AnnySubjects, Subject

    for proto in "ab":
        spec = load_protocol(f"olat_{proto}")
        source = AnnySubjects(DatasetPlan(out=Path("x"), spec=spec, settings=RenderSettings(), seed=3))
        subject = Subject(index=1, character=None, record={}, camera=None)  # random poses need only the index
        olat_pose = source.pose(subject, spec.split("olat"), 16 + 7)  # pose 1, direction 7
        test_pose = source.pose(subject, spec.split("test"), 1)
        assert json.dumps(olat_pose.to_json()) == json.dumps(test_pose.to_json()), proto
        assert json.dumps(source.pose(subject, spec.split("test"), 0).to_json()) != json.dumps(test_pose.to_json())
