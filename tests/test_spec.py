"""Scene/protocol descriptions: the shipped files load, and bad input is refused with a message naming it."""
from __future__ import annotations

import json

import pytest

from rh_dataset.spec import SpecError, available_protocols, load_protocol
from rh_dataset.presets import load_presets


def test_shipped_protocols_match_the_paper():
    a, b = load_protocol("a"), load_protocol("b")
    assert (a.subjects, b.subjects) == (49, 49)
    assert (a.split("train").frames, a.split("test").frames) == (100, 150)
    assert (a.split("train").poses, a.split("train").light) == ("turntable", "fixed")
    assert (a.split("test").poses, a.split("test").light) == ("random", "random")
    assert (b.split("train").frames, b.split("test").frames) == (150, 150)
    assert (b.split("train").poses, b.split("test").poses, b.split("test").light) == ("random", "train", "random")
    assert (a.width, a.height) == (512, 512)
    # Training splits carry only what a method may learn from.
    assert set(a.split("train").layers) == {"image", "mask"}
    assert {"albedo", "normal", "mask", "image"} <= set(a.split("test").layers)


def test_every_shipped_scene_and_preset_loads():
    for name in available_protocols():
        load_protocol(name)
    presets = load_presets()
    assert {"draft", "standard", "reference"} <= set(presets)
    assert presets["draft"].spp < presets["standard"].spp < presets["reference"].spp


def test_overrides_cap_frames_and_keep_protocol_b_consistent():
    b = load_protocol("b").with_overrides(frames=3, subjects=2, resolution=(64, 48))
    assert [s.frames for s in b.splits] == [3, 3] and b.subjects == 2 and (b.width, b.height) == (64, 48)
    assert b.digest() != load_protocol("b").digest()


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(colour="red"), "unknown key"),
    (lambda d: d.update(protocol="d"), "protocol must be"),
    (lambda d: d.update(resolution=[0, 512]), "resolution width"),
    (lambda d: d["splits"]["test"].update(poses="dance"), "poses must be"),
    (lambda d: d["splits"]["test"].update(layers=["image", "beauty"]), "layers"),
    (lambda d: d["splits"]["train"].update(frames=0), "frames must be"),
])
def test_bad_descriptions_are_refused_with_the_reason(tmp_path, mutate, message):
    data = json.loads(open(load_protocol("a").source).read())
    mutate(data)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=message):
        load_protocol(str(p))


def test_unknown_protocol_names_the_choices():
    with pytest.raises(SpecError, match="choose one of"):
        load_protocol("zz")


def test_mixed_scenes_keep_their_protocols_splits_and_add_only_the_mixture():
    for proto in "ab":
        base, mixed = load_protocol(proto), load_protocol(f"mixed_{proto}")
        assert mixed.protocol == proto and mixed.splits == base.splits
        assert base.light_mixture is None and "light_mixture" not in base.to_json()  # a and b keep their digest
        assert mixed.light_mixture == {"real": 0.4, "studio": 0.2, "window": 0.2, "outdoor": 0.2}
        assert mixed.digest() != base.digest()


@pytest.mark.parametrize("lights, message", [
    ({"mixture": {"real": 1, "disco": 1}}, "unknown kind 'disco'"),
    ({"mixture": {"real": 0}}, "sum to 0"),
    ({"sunsky": True, "mixture": {"real": 1}}, "weight in the mixture"),
])
def test_bad_light_mixture_refused_naming_the_file(tmp_path, lights, message):
    data = json.loads(open(load_protocol("a").source).read())
    data["lights"] = lights
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(data))
    with pytest.raises(SpecError, match=message) as info:
        load_protocol(str(p))
    assert str(p) in str(info.value) and "\n" not in str(info.value)
