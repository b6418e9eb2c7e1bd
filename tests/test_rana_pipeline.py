"""RANA end to end on a tiny synthetic subject (our rasteriser, Lambertian SH light): coarse geometry, coarse
albedo, personalization with checkpoints and resume, predictions that rh-eval accepts, the SMPL+D baseline, the
loss plot, and pretraining (TextureNet, G_N, G_A) feeding a personalization."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from rana.cli import main as rana_main
from rana.config import get_preset
from rana.runs import RunDir
from rana.synthetic import make_dataset

RES = 48


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    torch.set_num_threads(1)
    return make_dataset(tmp_path_factory.mktemp("rana_ds") / "ds", subjects=1, train_frames=6, test_frames=2,
                        resolution=RES, seed=5, texture_size=64, shell_m=0.02)


@pytest.fixture(scope="module")
def trained(dataset, tmp_path_factory):
    runs = tmp_path_factory.mktemp("rana_runs")
    rc = rana_main(["train", "--dataset", str(dataset), "--subject", "subject_000", "--runs", str(runs),
                    "--preset", "tiny", "--threads", "1", "--no-progress"])
    assert rc == 0
    return runs


def _validate(dataset, pred):
    from rh_eval.dataset_io import load_dataset, read_pred_albedo, read_pred_display, read_pred_normal, \
        scan_predictions

    ds = load_dataset(dataset, "a")
    idx = scan_predictions(pred, ds)
    assert len(idx.frames) == len(ds.frames) and idx.has_albedo and idx.has_normal
    for f in idx.frames:
        img = read_pred_display(f.image, f.gt)
        assert img.shape == (RES, RES, 3) and np.isfinite(img).all()
        read_pred_albedo(f.albedo, f.gt)
        n = read_pred_normal(f.normal, f.gt)
        norms = np.linalg.norm(n, axis=-1)
        assert np.allclose(norms[norms > 0], 1.0, atol=1e-3)


def test_coarse_stage_fits_the_silhouettes(trained):
    run = RunDir(trained / "subject_000")
    rec = [r for r in run.read_log() if r["step"] == -1][0]
    assert rec["iou_after"] > rec["iou_before"]  # the 2 cm 'garment' shell is found from the masks alone
    coarse = torch.load(run.path / "coarse.pt", weights_only=True)
    assert coarse["valid"].float().mean() > 0.2
    assert 0.0 <= float(coarse["albedo_texture"].min()) and float(coarse["albedo_texture"].max()) <= 1.0


def test_run_folder_has_config_checkpoints_and_log(trained):
    run = RunDir(trained / "subject_000")
    cfg, extra = run.read_config()
    assert cfg.preset == "tiny" and extra["subject"] == "subject_000"
    steps = [s for s, _ in run.checkpoints()]
    assert steps[-1] == cfg.personalize.steps and (run.ckpt_dir / "config.json").is_file()
    logged = [r["step"] for r in run.read_log() if r["step"] >= 0]
    assert logged == list(range(cfg.personalize.steps))


def test_resume_after_interruption_matches_uninterrupted(dataset, trained, tmp_path):
    from rana.train import personalize

    cfg = dataclasses.replace(get_preset("tiny"), threads=1)
    partial = personalize(dataset, "subject_000", "a", tmp_path / "r", cfg, progress=False, max_steps=4)
    assert [s for s, _ in partial.checkpoints()] == [3]  # killed after step 4: the newest checkpoint is 3
    personalize(dataset, "subject_000", "a", tmp_path / "r", cfg, progress=False)  # resumes at 3
    logged = [r["step"] for r in partial.read_log() if r["step"] >= 0]
    assert logged == list(range(cfg.personalize.steps))  # no duplicated or missing steps
    a = RunDir(tmp_path / "r").load()["model"]
    b = RunDir(trained / "subject_000").load()["model"]
    for k in ("Z", "E"):
        assert torch.allclose(a[k], b[k], atol=1e-5), k
    with pytest.raises(ValueError):  # other settings on the same folder are refused
        personalize(dataset, "subject_000", "a", tmp_path / "r", dataclasses.replace(cfg, seed=9), progress=False)


def test_predictions_pass_rh_eval_validation(dataset, trained, tmp_path):
    assert rana_main(["predict", "--dataset", str(dataset), "--runs", str(trained), "--out", str(tmp_path / "p"),
                      "--no-progress"]) == 0
    _validate(dataset, tmp_path / "p")
    assert json.loads((tmp_path / "p" / "method.json").read_text())["name"] == "RANA"


def test_smpld_baseline_predicts_through_the_same_writer(dataset, trained, tmp_path):
    assert rana_main(["smpld", "--dataset", str(dataset), "--runs", str(trained), "--out", str(tmp_path / "s"),
                      "--no-progress"]) == 0
    _validate(dataset, tmp_path / "s")


def _masked_psnr(dataset, pred) -> float:
    """Mean image PSNR inside the ground-truth mask: rh-eval's `mask` region, through the public per-frame scorer."""
    from rh_eval import Convention, read_frame, score_frame
    from rh_eval.dataset_io import load_dataset, scan_predictions

    conv = Convention(region="mask")
    frames = scan_predictions(pred, load_dataset(dataset, "a")).frames
    return float(np.mean([score_frame(*read_frame(f, ("psnr",), layers=("image",)), conv, ("psnr",)).image.psnr
                          for f in frames]))


def test_rana_is_not_worse_than_its_smpld_initialisation(dataset, trained, tmp_path):
    # RANA starts from SMPL+D (residual heads, E from the coarse light) and a few steps must not wreck it. Before the
    # fix an untrained RANA scored ~6 dB below SMPL+D inside the person (random albedo/normal/mask heads).
    assert rana_main(["predict", "--dataset", str(dataset), "--runs", str(trained), "--out", str(tmp_path / "p"),
                      "--no-progress"]) == 0
    assert rana_main(["smpld", "--dataset", str(dataset), "--runs", str(trained), "--out", str(tmp_path / "s"),
                      "--no-progress"]) == 0
    rana, smpld = _masked_psnr(dataset, tmp_path / "p"), _masked_psnr(dataset, tmp_path / "s")
    assert rana > smpld - 1.0, (rana, smpld)


def test_plot_writes_a_png(trained, tmp_path):
    assert rana_main(["plot", str(trained / "subject_000"), "--out", str(tmp_path / "l.png")]) == 0
    assert (tmp_path / "l.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_pretrain_then_personalize_with_it(tmp_path):
    torch.set_num_threads(1)
    pre_ds = make_dataset(tmp_path / "pre", subjects=2, train_frames=3, test_frames=1, resolution=32, seed=8,
                          texture_size=32, pool="pretrain", aov_only_train=True)
    assert rana_main(["pretrain", "--dataset", str(pre_ds), "--out", str(tmp_path / "pt"), "--preset", "tiny",
                      "--threads", "1", "--no-progress", "--model.resolution", "32"]) == 0
    pre = torch.load(tmp_path / "pt" / "pretrained.pt", weights_only=True)
    assert {"G_N", "G_A", "texturenet"} <= set(pre)
    assert [s for s, _ in RunDir(tmp_path / "pt").checkpoints()][-1] == get_preset("tiny").pretrain.steps
    # A benchmark-pool subject personalised from the pretrained networks; G_N must not change.
    ds = make_dataset(tmp_path / "ds", subjects=1, train_frames=3, test_frames=1, resolution=32, seed=9,
                      texture_size=32)
    assert rana_main(["train", "--dataset", str(ds), "--runs", str(tmp_path / "runs"), "--preset", "tiny",
                      "--threads", "1", "--no-progress", "--model.resolution", "32",
                      "--pretrained", str(tmp_path / "pt" / "pretrained.pt")]) == 0
    st = RunDir(tmp_path / "runs" / "subject_000").load()["model"]
    for k, v in pre["G_N"].items():
        assert torch.equal(st["G_N." + k], v), k
    coarse = torch.load(tmp_path / "runs" / "subject_000" / "coarse.pt", weights_only=True)
    assert coarse["albedo_source"] == "texturenet(exposure-sh)"  # the tiny preset's input mode
    assert pre["config"]["texture"]["texturenet_input"] == "exposure-sh"
    assert coarse["light_world"] is not None  # the de-lighting's light, E's start


def test_texturenet_resume_equals_an_uninterrupted_run(tmp_path):
    """Kill TextureNet training after its first checkpoint, resume: the weights equal an uninterrupted run's."""
    import shutil

    from rana.pretrain import prepare_character, train_texturenet

    torch.set_num_threads(1)
    cfg = get_preset("tiny")
    cfg = dataclasses.replace(cfg, model=dataclasses.replace(cfg.model, resolution=32),
                              pretrain=dataclasses.replace(cfg.pretrain, checkpoint_every=2, log_every=1))
    pre_ds = make_dataset(tmp_path / "pre", subjects=2, train_frames=3, test_frames=1, resolution=32, seed=8,
                          texture_size=32, pool="pretrain", aov_only_train=True)
    chars = [prepare_character(pre_ds, s, "a", cfg) for s in ("subject_000", "subject_001")]
    full = train_texturenet(chars, cfg, RunDir(tmp_path / "full"), progress=False)
    steps = [s for s, _ in RunDir(tmp_path / "full").checkpoints()]
    assert steps == [2, 4]
    shutil.copytree(tmp_path / "full", tmp_path / "cut")
    (tmp_path / "cut" / "checkpoints" / "step-000000004.pt").unlink()  # the run died between step 2 and step 4
    resumed = train_texturenet(chars, cfg, RunDir(tmp_path / "cut"), progress=False)
    for (k, a), b in zip(full.state_dict().items(), resumed.state_dict().values()):
        assert torch.equal(a, b), k
    log = [r["step"] for r in RunDir(tmp_path / "cut").read_log()]
    assert log == sorted(set(log)) == list(range(4))  # no duplicated stretch after the resume
