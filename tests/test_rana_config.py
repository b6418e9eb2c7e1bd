"""RANA configuration: presets, per-field docs as CLI help, JSON round trip."""
from __future__ import annotations

import argparse
import dataclasses

import pytest

from rana.config import (PRESETS, RanaConfig, add_config_flags, apply_config_flags, config_from_json, config_to_json,
                         field_docs, get_preset)


def test_presets_exist_and_paper_uses_paper_numbers():
    assert {"paper", "cpu"} <= set(PRESETS)
    p = get_preset("paper")
    assert p.model.resolution == 512 and p.model.latent_size == 256 and p.model.latent_channels == 16
    assert p.personalize.steps == 15000 and p.personalize.freeze_albedo_steps == 1000
    L = p.loss
    assert (L.lambda_face, L.lambda_mask, L.lambda_vgg, L.lambda_gan, L.lambda_albedo_reg, L.lambda_normal_reg) == \
        (1.0, 10.0, 5.0, 0.1, 0.5, 0.25)
    assert p.loss.blur_kernel == 51 and p.texture.batch_size == 8 and p.pretrain.batch_size == 16


def test_every_field_has_a_docstring():
    for cls in (RanaConfig, *[type(getattr(RanaConfig(), f.name)) for f in dataclasses.fields(RanaConfig)
                              if dataclasses.is_dataclass(getattr(RanaConfig(), f.name))]):
        docs = field_docs(cls)
        missing = [f.name for f in dataclasses.fields(cls) if not docs.get(f.name)]
        assert not missing, f"{cls.__name__}: fields without docstring {missing}"


def test_flags_override_the_preset_and_json_round_trips():
    p = argparse.ArgumentParser()
    add_config_flags(p)
    args = p.parse_args(["--model.resolution", "64", "--personalize.finetune_normal", "true", "--seed", "3"])
    cfg = apply_config_flags(get_preset("cpu"), args)
    assert cfg.model.resolution == 64 and cfg.personalize.finetune_normal and cfg.seed == 3
    assert cfg.model.latent_size == get_preset("cpu").model.latent_size
    assert config_from_json(config_to_json(cfg)) == cfg
    with pytest.raises(ValueError):
        config_from_json({**config_to_json(cfg), "bogus": 1})
    assert "Z: channels" in p.format_help()
