"""RANA configuration: presets, per-field docs as CLI help, validation on construction, the JSON form with its
schema version, older configs, and checkpoints that load with `torch.load(weights_only=True)`."""
from __future__ import annotations

import argparse
import dataclasses
import json
import typing

import pytest
import torch

from rana.config import PRESETS, SECTIONS, RanaConfig, field_types, get_preset
from rana.config_flags import add_config_flags, apply_config_flags, field_docs
from rana.config_json import SCHEMA, config_from_json, config_from_repr, config_to_json


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


def _literal_fields():
    for sec, cls in SECTIONS.items():
        for name, t in field_types(cls).items():
            if typing.get_origin(t) is typing.Literal:
                yield sec, cls, name, typing.get_args(t)


def test_every_mode_field_is_a_literal_checked_on_construction():
    modes = {(sec, name) for sec, _, name, _ in _literal_fields()}
    assert {("texture", "texturenet_input"), ("texture", "delight_mode"), ("pretrain", "light_source")} <= modes
    for sec, cls, name, allowed in _literal_fields():
        for ok in allowed:
            assert getattr(cls(**{name: ok}), name) == ok
        with pytest.raises(ValueError) as e:
            cls(**{name: "median"})
        msg = str(e.value)
        assert "\n" not in msg and f"{sec}.{name}" in msg and "'median'" in msg and all(a in msg for a in allowed)


@pytest.mark.parametrize("sec, name, bad", [("geometry", "steps", 0), ("model", "resolution", -8),
                                             ("personalize", "lr_net", 0.0), ("loss", "lambda_vgg", -1.0),
                                             ("texture", "facing_quantile", 1.5), ("pretrain", "light_seed", -1),
                                             ("personalize", "checkpoint_every", 0), ("geometry", "lr", float("nan")),
                                             ("model", "resolution", 64.0), ("model", "residual_coarse", 1),
                                             ("personalize", "steps", True)])
def test_bad_counts_weights_and_types_are_refused_on_construction(sec, name, bad):
    with pytest.raises(ValueError, match=rf"^{sec}\.{name}: "):
        SECTIONS[sec](**{name: bad})


def test_a_bad_flag_value_fails_before_any_work_and_modes_list_their_choices():
    p = argparse.ArgumentParser()
    add_config_flags(p)
    with pytest.raises(ValueError, match="personalize.steps"):
        apply_config_flags(get_preset("tiny"), p.parse_args(["--personalize.steps", "0"]))
    with pytest.raises(SystemExit):  # argparse refuses a mode outside its choices
        p.parse_args(["--texture.delight_mode", "median"])
    assert "grey-world" in p.format_help()
    assert apply_config_flags(get_preset("tiny"), p.parse_args(["--texture.delight_mode", "grey-world"])) \
        .texture.delight_mode == "grey-world"


def test_int_for_a_float_field_is_stored_as_a_float():
    assert SECTIONS["geometry"](lr=1).lr == 1.0 and type(SECTIONS["geometry"](lr=1).lr) is float


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_json_round_trip_is_exact(name):
    cfg = PRESETS[name]
    d = config_to_json(cfg)
    assert d["schema"] == SCHEMA == "rana-config/2"
    assert config_from_json(d) == cfg
    assert config_from_json(json.loads(json.dumps(d))) == cfg  # through the file, types included
    assert config_to_json(config_from_json(json.loads(json.dumps(d)))) == d


def test_schema_mismatch_and_bad_keys_give_one_line_errors():
    d = config_to_json(get_preset("tiny"))
    for bad, match in [({**d, "schema": "rana-config/3"}, "schema 'rana-config/3'"),
                       ({**d, "bogus": 1}, "unknown key"),
                       ({**d, "model": {**d["model"], "bogus": 1}}, r"config\.model: unknown key"),
                       ({k: v for k, v in d.items() if k != "seed"}, "missing key"),
                       ({**d, "model": "tiny"}, r"config\.model: expected a JSON object")]:
        with pytest.raises(ValueError, match=match) as e:
            config_from_json(bad)
        assert "\n" not in str(e.value)


def test_an_old_format_config_still_loads():
    """config.json as the code before the schema wrote it: `dataclasses.asdict` without "schema", and from runs
    older still, without the fields added since (read at the values those runs used)."""
    cfg = get_preset("cpu")
    old = dataclasses.asdict(cfg)
    assert config_from_json(old) == cfg
    del old["model"]["residual_coarse"], old["texture"]["texturenet_input"], old["pretrain"]["light_source"]
    got = config_from_json(old)
    assert (got.model.residual_coarse, got.texture.texturenet_input, got.pretrain.light_source) == \
        (False, "shaded", "random-sh")
    assert got.model.resolution == cfg.model.resolution and got.personalize == cfg.personalize


def test_an_old_run_folder_reads_and_resumes(tmp_path):
    from rana.runs import RunDir
    from rh_common.imageio import write_json

    cfg = get_preset("tiny")
    extra = {"dataset": "/d", "subject": "subject_000", "protocol": "a", "pretrained": None}
    write_json(tmp_path / "config.json", {"config": dataclasses.asdict(cfg), **extra})  # the old writer's form
    run = RunDir(tmp_path)
    assert run.read_config() == (cfg, extra)
    run.init_config(cfg, extra)  # the same settings: a resume, not a mismatch
    assert json.loads((tmp_path / "config.json").read_text())["config"]["schema"] == SCHEMA


def test_an_old_pretrained_config_repr_is_read_without_eval():
    cfg = get_preset("tiny")
    assert config_from_repr(repr(cfg)) == cfg
    older = repr(cfg).replace("residual_coarse=True, ", "")  # before the residual heads
    assert config_from_repr(older).model.residual_coarse is False
    for evil in ["__import__('os').system('true')", "RanaConfig(seed=__import__('os').getpid())",
                 "RanaConfig(model=dict(resolution=8))"]:
        with pytest.raises(ValueError, match="not a stored RanaConfig repr"):
            config_from_repr(evil)


def _trained_state(cfg):
    """A personalization state whose optimizers hold state, as after training steps."""
    from rana.train import build_training_state

    st = build_training_state(cfg, use_vgg=False)
    for p in list(st.model.parameters()) + list(st.disc.parameters()):
        p.grad = torch.full_like(p, 1e-3)
    st.opt_latent.step(), st.opt_net.step(), st.opt_disc.step()
    return st


def test_checkpoints_of_train_and_pretrain_load_with_weights_only(tmp_path):
    from rana.runs import Pretrained, RunDir
    from rana.texturenet import TextureNet
    from rana.train import Coarse, build_training_state, load_coarse, save_coarse

    cfg = get_preset("tiny")
    torch.manual_seed(0)
    st = _trained_state(cfg)
    run = RunDir(tmp_path / "run")
    run.init_config(cfg)
    path = run.save(6, st.state_dict())
    raw = torch.load(path, weights_only=True)
    assert raw["step"] == 6 and raw["opt_net"]["state"]
    st2 = build_training_state(cfg, use_vgg=False)
    st2.load_state_dict(run.load())
    for k, v in st.model.state_dict().items():
        assert torch.equal(st2.model.state_dict()[k], v), k

    co = Coarse(torch.zeros(5, 3), torch.rand(3, 4, 4), torch.ones(4, 4, dtype=torch.bool), torch.rand(3, 4, 4),
                "exposure-sh", 0.5, 0.75, torch.rand(9, 3, dtype=torch.float64))
    save_coarse(co, tmp_path / "coarse.pt")
    torch.load(tmp_path / "coarse.pt", weights_only=True)
    back = load_coarse(tmp_path / "coarse.pt")
    assert back.albedo_source == "exposure-sh" and back.iou_after == 0.75 and torch.equal(back.offsets, co.offsets)

    pre = Pretrained(st.model.G_N.state_dict(), st.model.G_A.state_dict(), cfg, TextureNet(cfg.texture).state_dict(),
                     ["subject_000"])
    pre.save(tmp_path / "pretrained.pt")
    raw = torch.load(tmp_path / "pretrained.pt", weights_only=True)
    assert raw["config"]["schema"] == SCHEMA and isinstance(raw["config"], dict)
    back = Pretrained.load(tmp_path / "pretrained.pt")
    assert back.config == cfg and back.subjects == ["subject_000"] and back.texturenet_input == "exposure-sh"
    model = build_training_state(cfg, back, use_vgg=False).model  # the pretraining's residual heads: accepted
    for k, v in back.G_A.items():
        assert torch.equal(model.G_A.state_dict()[k], v), k


def test_an_old_pretrained_file_loads_and_its_config_fields_are_read(tmp_path):
    """pretrained.pt as rana-pretrain wrote it before the schema: `repr(config)`, a separate texturenet_input."""
    from rana.runs import Pretrained
    from rana.train import build_training_state

    cfg = get_preset("tiny")
    st = build_training_state(cfg, use_vgg=False)
    old = {"G_N": st.model.G_N.state_dict(), "G_A": st.model.G_A.state_dict(), "texturenet": None,
           "texturenet_input": "exposure-sh", "config": cfg.__repr__(), "subjects": ["subject_000"]}
    torch.save(old, tmp_path / "pretrained.pt")
    back = Pretrained.load(tmp_path / "pretrained.pt")
    assert back.config == cfg and back.texturenet_input == "exposure-sh"
    # Pretrained before the residual heads: refused by a run with them, with the flag that fits.
    torch.save({**old, "config": cfg.__repr__().replace("residual_coarse=True, ", "")}, tmp_path / "direct.pt")
    with pytest.raises(ValueError, match="residual_coarse false"):
        build_training_state(cfg, Pretrained.load(tmp_path / "direct.pt"), use_vgg=False)


def test_a_checkpoint_holding_other_objects_is_refused_in_one_line(tmp_path):
    from rana.runs import RunDir

    run = RunDir(tmp_path)
    run.ckpt_dir.mkdir(parents=True)
    torch.save({"step": 1, "model": {}, "args": argparse.Namespace(x=1)}, run.ckpt_dir / "step-000000001.pt")
    with pytest.raises(ValueError, match="rana train") as e:
        run.load()
    assert "\n" not in str(e.value)
