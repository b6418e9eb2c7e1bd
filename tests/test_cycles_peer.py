"""The Cycles peer of bench/bench_cycles.py: Cycles must render our scene conventions exactly as Mitsuba does.

With Lambertian materials the physics is identical, so after enough samples the two renderers must agree: the same
projection (mask IoU, reprojection of points), the same environment orientation (the background seen directly),
the same texture orientation and colour space (block means over the object), the same brightness (per-channel
means over the mask). Small: 64x64, Mitsuba 256 spp, Cycles 128 spp; the Blender process takes a few seconds.
"""
from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from analytic_scenes import uv_sphere
from rh_dataset.lights import LightSpec, build_light, bundled_hdris, load_hdri, mitsuba_emitter_dict, normalised_scale
from rh_common.camera import Camera
from rh_dataset.render.passes import render_frame
from rh_dataset.render.scene import RenderSettings
from rh_dataset.variant import select_variant

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


@pytest.fixture(scope="module")
def bc():
    sys.path.insert(0, str(ROOT / "bench"))
    spec = importlib.util.spec_from_file_location("bench_cycles", ROOT / "bench" / "bench_cycles.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_cycles"] = mod
    spec.loader.exec_module(mod)
    return mod


def _texture(n: int = 64) -> np.ndarray:
    """Asymmetric in both axes: red grows with u, brightness with v (row 0 = top = v 1), a blue stripe at u < 0.2.
    A flipped, mirrored or sRGB-decoded texture changes the block means the test compares."""
    v = 1.0 - (np.arange(n) + 0.5) / n
    u = (np.arange(n) + 0.5) / n
    U, V = np.meshgrid(u, v)
    t = np.stack([0.15 + 0.7 * U, 0.1 + 0.6 * V, np.where(U < 0.2, 0.8, 0.1)], -1)
    return t.astype(np.float32)


@pytest.fixture(scope="module")
def scene(tmp_path_factory, bc):
    """A textured sphere (Lambertian, two-sided as garments are) and a small plain one, under the bundled `interior`
    HDRI rotated by 70 deg, seen from an oblique camera."""
    lib = bundled_hdris()
    base, _ = load_hdri(lib["interior"])
    light = build_light(LightSpec("envmap", "interior", str(lib["interior"]), 70.0, normalised_scale(base)))
    big = uv_sphere(center=(0.0, 0.0, 0.0), radius=1.0, texture=_texture(), n_lat=48, n_lon=96)
    big.material.two_sided = True
    small = uv_sphere(center=(1.1, -0.6, 0.9), radius=0.3, albedo=(0.6, 0.5, 0.4), n_lat=24, n_lon=48, name="small")
    meshes = [big, small]
    cam = Camera(width=64, height=64, fov_y_deg=45.0, origin=(1.2, -4.0, 1.0), target=(0.1, 0.0, 0.1))
    work = tmp_path_factory.mktemp("cycles")
    npz = bc.export_scene(work / "scene.npz", meshes, light.radiance, light.spec.rotation_deg, cam)
    return SimpleNamespace(meshes=meshes, light=light, cam=cam, npz=npz, work=work)


@pytest.fixture(scope="module")
def renders(scene, bc):
    st = RenderSettings(spp=256, aov_spp=64, max_depth=4)
    mi_out = render_frame(scene.meshes, mitsuba_emitter_dict(scene.light), scene.cam, st, ["image", "mask"], seed=3)
    cy = bc.render_cycles(scene.npz, "diffuse", 4, [{"spp": 128, "seed": 1}, {"spp": 32, "seed": 2, "mask": True}],
                          camera_check=True, workdir=scene.work, timeout=600)
    return SimpleNamespace(m_img=mi_out.layers["image"], m_mask=mi_out.layers["mask"], c_img=cy["renders"][0]["image"],
                           c_mask=cy["renders"][1]["mask"], report=cy)


def test_cycles_report_is_complete_and_times_are_split(renders):
    r = renders.report
    assert r["blender"].startswith("5.")
    assert r["view_transform"] == "Standard"
    for k in r["renders"]:
        assert k["sync_s"] >= 0 and k["render_s"] > 0 and k["sync_s"] + k["render_s"] <= k["wall_s"] + 1e-6
    assert renders.c_img.shape == (64, 64, 3) and renders.c_img.dtype == np.float32
    assert np.all(np.isfinite(renders.c_img)) and renders.c_img.min() >= 0


def test_same_projection(renders):
    assert renders.report["camera_max_px_error"] < 1e-3  # Blender's projection of 200 points vs K @ world_to_camera
    A, B = renders.m_mask >= 0.5, renders.c_mask >= 0.5
    iou = np.count_nonzero(A & B) / np.count_nonzero(A | B)
    assert iou > 0.98, iou
    # coverage agrees pixel by pixel up to edge-sampling noise
    assert float(np.mean(np.abs(renders.m_mask - renders.c_mask))) < 0.005


def test_same_environment_orientation(renders):
    """Pixels that see only the environment: both renderers show the same directions of the same map."""
    bg = (renders.m_mask <= 1e-6) & (renders.c_mask <= 1e-6)
    m, c = renders.m_img[bg].astype(np.float64), renders.c_img[bg].astype(np.float64)
    rel = np.abs(c - m).sum(1) / (m.sum(1) + 0.05 * m.sum(1).mean())
    assert np.median(rel) < 0.03, np.median(rel)
    # a 180 deg (or any gross) mistake would decorrelate the background completely
    assert np.corrcoef(m.sum(1), c.sum(1))[0, 1] > 0.98


def test_same_radiance_on_the_object(renders):
    """Lambertian physics is identical, so the converged images agree: per-channel mean over the mask to 1 %
    (measured: within 0.15 %; a flipped environment or an sRGB-decoded texture moves it by far more), and 8x8-block
    means (texture orientation, shading direction) to 6 % (measured: 2.2 %, the blocks' own noise)."""
    inside = (renders.m_mask >= 0.999) & (renders.c_mask >= 0.999)
    m, c = renders.m_img.astype(np.float64), renders.c_img.astype(np.float64)
    ratio = c[inside].mean(0) / m[inside].mean(0)
    np.testing.assert_allclose(ratio, 1.0, atol=0.01)
    blocks = []
    for y in range(0, 64, 8):
        for x in range(0, 64, 8):
            sel = inside[y:y + 8, x:x + 8]
            if sel.sum() >= 48:
                blocks.append((m[y:y + 8, x:x + 8][sel].mean(0), c[y:y + 8, x:x + 8][sel].mean(0)))
    assert len(blocks) >= 12
    bm = np.array([b[0] for b in blocks])
    bcy = np.array([b[1] for b in blocks])
    rel = np.abs(bcy - bm) / bm.mean(0)
    assert rel.max() < 0.06, rel.max()


def test_off_centre_principal_point_and_non_square_image(bc, tmp_path):
    """Blender's camera shift reproduces an off-centre principal point: a tiny sphere lands at K @ world_to_camera."""
    w2c = Camera(width=80, height=48, fov_y_deg=40.0, origin=(0.0, -4.0, 0.0), target=(0.0, 0.0, 0.0)).world_to_camera
    K = np.array([[60.0, 0.0, 27.0], [0.0, 60.0, 30.0], [0.0, 0.0, 1.0]])
    cam = SimpleNamespace(width=80, height=48, K=K, world_to_camera=w2c)
    centre = np.array([0.35, 0.2, -0.25])
    sphere = uv_sphere(center=tuple(centre), radius=0.06, n_lat=16, n_lon=32)
    npz = bc.export_scene(tmp_path / "s.npz", [sphere], np.ones((8, 16, 3), np.float32), 0.0, cam)
    rep = bc.render_cycles(npz, "diffuse", 2, [{"spp": 64, "seed": 0, "mask": True}], camera_check=True,
                           workdir=tmp_path, timeout=300)
    assert rep["camera_max_px_error"] < 1e-3
    a = rep["renders"][0]["mask"]
    assert a.shape == (48, 80)
    ys, xs = np.mgrid[0:48, 0:80]
    got = np.array([(a * (xs + 0.5)).sum(), (a * (ys + 0.5)).sum()]) / a.sum()  # pixel centres at +0.5
    pc = w2c[:3, :3] @ centre + w2c[:3, 3]
    want = (K @ pc)[:2] / pc[2]
    np.testing.assert_allclose(got, want, atol=0.1)
    # its area is the analytic disc's (radius = f * r / z, small-angle), to sampling noise
    assert abs(a.sum() / (math.pi * (60.0 * 0.06 / pc[2]) ** 2) - 1) < 0.05


def test_equal_error_time_recovers_a_known_ratio(bc):
    """Two power laws e = c / t with c_a = 3 c_b: at any error, renderer a needs 3x the time."""
    t = np.geomspace(0.1, 100.0, 11)
    ea, eb = 3.0 / t, 1.0 / t
    for level in (0.05, 0.3, 2.0):
        r = bc.equal_error_time(t, ea, level) / bc.equal_error_time(t, eb, level)
        assert r == pytest.approx(3.0, rel=1e-9)
    assert math.isnan(bc.equal_error_time(t, eb, 1e-4))  # outside the measured range: no extrapolation
    # a noisy bump (error rising at a later time) does not create a second crossing
    assert bc.equal_error_time([1, 2, 3, 4], [1.0, 0.5, 0.6, 0.25], 0.55) == pytest.approx(
        math.exp(math.log(1) + (math.log(0.55) - 0) / (math.log(0.5) - 0) * math.log(2)))
    a, s = bc.power_fit(t, eb)
    assert s == pytest.approx(-1.0) and bc.fit_time((a, s), 0.3) == pytest.approx(1 / 0.3)


def test_lambertian_variant_keeps_texture_and_sidedness(bc):
    from rh_dataset.characters.character import Material, PosedMesh

    tex = _texture(8)
    m = PosedMesh("p", np.zeros((3, 3), np.float32), np.tile([0, 0, 1], (3, 1)).astype(np.float32),
                  np.array([[0, 1, 2]], np.int32), np.zeros((3, 2), np.float32), Material(tex, 0.4, 0.35, False))
    (d,) = bc.lambertian([m])
    assert d.material.specular == 0.0 and d.material.two_sided is False and d.material.roughness == 0.4
    np.testing.assert_array_equal(d.material.albedo, tex)
    assert m.material.specular == 0.35  # the original is untouched


def test_agreement_tells_a_few_differently_shaded_pixels_from_noise(bc):
    """The share of the mask holding 90 % of the difference: most of it for noise spread over the person, one
    pixel's share where a single pixel differs (a shading convention at a silhouette, not noise); unreached
    equal-error levels are null in the JSON, not an invalid NaN."""
    rng = np.random.default_rng(0)
    ref = np.full((40, 40, 3), 0.5)
    mask = np.ones((40, 40))
    mask[:, :5] = 0.0  # a strip of background
    noisy = ref * (1 + 0.05 * rng.standard_normal(ref.shape))
    spread = bc.agreement(noisy, ref, mask)["share_for_90"]
    assert 0.5 < spread < 0.95
    one = ref.copy()
    one[20, 20] *= 3.0
    a = bc.agreement(one, ref, mask)
    assert a["share_for_90"] == pytest.approx(1 / mask.sum())
    assert a["mean_ratio_rgb"][0] == pytest.approx(1 + 2.0 / mask.sum())  # one pixel of 1,400 at 3x
    assert a["relmse_background"] == 0.0
    assert bc.agreement(ref, ref, np.ones((40, 40)))["relmse_background"] is None
    assert bc._finite(float("nan")) is None and bc._finite(2.0) == 2.0
