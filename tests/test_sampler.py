"""The sampler as a render setting: names refused with one line, counts a sampler would round refused, the shipped
presets' counts taken exactly, same seed -> same bits, and different frames' noise uncorrelated."""
from __future__ import annotations

import json

import numpy as np
import pytest

from analytic_scenes import uv_sphere
from rh_common.camera import Camera
from rh_dataset.render.passes import render_frame
from rh_dataset.render.sampler import SAMPLERS, check_spp, taken_spp
from rh_dataset.render.scene import RenderSettings
from rh_dataset.spec import SCENES_DIR, SpecError
from rh_dataset.presets import load_presets
from rh_dataset.variant import select_variant


@pytest.fixture(scope="module", autouse=True)
def _variant():
    select_variant("llvm_ad_rgb")


ENV = {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}}


def _cam(n=32) -> Camera:
    return Camera(width=n, height=n, fov_y_deg=40.0, origin=(0.0, -4.0, 0.0), target=(0.0, 0.0, 0.0))


def test_an_unknown_sampler_name_is_refused_in_settings_and_in_a_presets_file(tmp_path):
    with pytest.raises(ValueError, match="sampler must be one of independent"):
        RenderSettings(sampler="sobol")
    data = json.loads((SCENES_DIR / "presets.json").read_text())
    data["presets"]["draft"]["sampler"] = "sobol"
    bad = tmp_path / "presets.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=r"presets\.json: preset draft: unknown sampler 'sobol'; choose one of") as e:
        load_presets(bad)
    assert "\n" not in str(e.value)


def test_counts_a_sampler_rounds_are_refused_naming_the_counts_it_takes():
    assert taken_spp("independent", 128) == 128
    assert taken_spp("stratified", 128) == 144 and taken_spp("ldsampler", 128) == 256
    with pytest.raises(ValueError, match=r"multijitter sampler renders 132 .* spp=128; set spp to one it takes "
                                         r"\(121, 132\)"):
        check_spp("multijitter", 128)
    with pytest.raises(ValueError, match="aov_spp"):
        render_frame([uv_sphere()], ENV, _cam(8), RenderSettings(spp=4, aov_spp=8, max_depth=2, sampler="ldsampler"),
                     ["image", "mask"], seed=0)


def test_every_shipped_preset_renders_exactly_its_sample_counts():
    from rh_dataset.render.passes import _chunks

    for name, p in load_presets().items():
        for n in _chunks(p.spp):
            assert taken_spp(p.sampler, n) == n, (name, p.sampler, n)
        assert taken_spp(p.sampler, p.aov_spp) == p.aov_spp, (name, p.sampler, p.aov_spp)


@pytest.mark.parametrize("sampler", ["multijitter", "ldsampler"])
def test_same_seed_same_bits_and_frames_noise_uncorrelated(sampler):
    # A grey convex sphere under constant light: every inside pixel's exact value is a * L (test_render.py), so
    # what a render adds to it is pure sampling noise. Two frames (seeds) must give the same bits per seed, and
    # their noise must be uncorrelated, pixel by pixel and between neighbouring pixels of one frame.
    a = 0.5
    st = RenderSettings(spp=4, aov_spp=4, max_depth=2, sampler=sampler)
    scene = [uv_sphere(albedo=(a, a, a))]
    f1 = render_frame(scene, ENV, _cam(), st, ["image", "mask"], seed=11).layers
    f1b = render_frame(scene, ENV, _cam(), st, ["image", "mask"], seed=11).layers
    f2 = render_frame(scene, ENV, _cam(), st, ["image", "mask"], seed=12).layers
    for k in f1:
        assert np.array_equal(f1[k], f1b[k]), k
    inside = (f1["mask"] > 0.999) & (f2["mask"] > 0.999)
    n1 = f1["image"][..., 0].astype(np.float64) - a
    n2 = f2["image"][..., 0].astype(np.float64) - a
    assert inside.sum() > 300 and n1[inside].std() > 1e-3  # there is noise to correlate
    bound = 4.0 / np.sqrt(inside.sum())  # |r| of independent noise is below 4 standard errors
    assert abs(np.corrcoef(n1[inside], n2[inside])[0, 1]) < bound
    pair = inside[:, 1:] & inside[:, :-1]
    assert abs(np.corrcoef(n1[:, 1:][pair], n1[:, :-1][pair])[0, 1]) < 4.0 / np.sqrt(pair.sum())


def test_sampler_names_are_mitsubas():
    import mitsuba as mi

    for name in SAMPLERS:
        assert mi.load_dict({"type": name, "sample_count": 4}) is not None


def test_env_spp_is_checked_in_a_presets_file_and_a_frame_without_coverage_renders_every_pixel(tmp_path):
    data = json.loads((SCENES_DIR / "presets.json").read_text())
    data["presets"]["draft"]["env_spp"] = data["presets"]["draft"]["spp"] + 1
    bad = tmp_path / "presets.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=r"preset draft: env_spp must be an integer in \[1, spp\]"):
        load_presets(bad)
    st = RenderSettings(spp=4, aov_spp=4, max_depth=2, sampler="multijitter", env_spp=1)
    image_only = render_frame([uv_sphere()], ENV, _cam(8), st, ["image"], seed=0)
    assert "focus" not in image_only.info  # no AOV pass ran, so no coverage: every pixel got spp
    with_mask = render_frame([uv_sphere()], ENV, _cam(8), st, ["image", "mask"], seed=0)
    assert with_mask.info["focus"]["env_spp"] == 1 and with_mask.info["focus"]["pixels"] > 0
