"""rh-eval end to end on a tiny fake dataset: identity, conventions, caching, and every refused prediction set."""
from __future__ import annotations

import csv
import json
import math
import shutil
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest

from rh_common.imageio import read_exr, read_png, write_exr, write_png
from rh_eval.cli import build_parser, main
from rh_eval.conventions import Convention, MIN_CROP, compute_region, margin_for
from rh_eval.evaluate import EvalOptions, Evaluator
from rh_eval.metrics.lpips import get_lpips_net
from test_eval_fake import make_dataset, make_predictions

FRAME_DIR = Path("subject_000/protocol_a/test")


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("ds") / "data")


@pytest.fixture(scope="module")
def oracle(ds, tmp_path_factory):
    return make_predictions(ds, tmp_path_factory.mktemp("pred") / "oracle", kind="bound")


@pytest.fixture(scope="module")
def noisy(ds, tmp_path_factory):
    return make_predictions(ds, tmp_path_factory.mktemp("pred") / "noisy", name="noisy", noise=0.05, fmt="png")


def _run(args, capsys):
    code = main([str(a) for a in args] + ["--no-progress"])
    out = capsys.readouterr()
    return code, out.out, out.err


# --------------------------------------------------------------------------------------------- identity
def test_ground_truth_against_itself(ds, oracle, tmp_path, capsys):
    out = tmp_path / "res" / "oracle.json"
    code, stdout, err = _run([oracle, "--dataset", ds, "--protocol", "a", "--out", out, "--align-albedo"], capsys)
    assert code == 0, err
    res = json.loads(out.read_text())
    ov = res["overall"]
    for layer in ("image", "albedo", "albedo_aligned"):
        assert ov[f"{layer}_psnr"]["mean"] == "inf" and ov[f"{layer}_psnr"]["n_infinite"] == 4
        assert ov[f"{layer}_psnr"]["std"] is None
        assert ov[f"{layer}_ssim"]["mean"] == 1.0
        for m in ("lpips", "dists", "flip"):
            assert ov[f"{layer}_{m}"]["mean"] == 0.0, (layer, m)
    assert ov["normal_deg"]["mean"] == 0.0
    assert res["kind"] == "bound" and res["complete"] is True
    assert res["n_frames_evaluated"] == 4 and res["dataset"]["n_frames"] == 4
    assert len(res["dataset"]["manifest_sha256"]) == 64
    assert res["convention"]["backbone"] == "alex" and res["convention"]["region"] == "default"
    assert set(res["weights"]) == {"alexnet", "vgg16", "lpips_alex_v0.1", "dists_alpha_beta"}
    assert res["flip_ppd"] == pytest.approx(67.0206, abs=1e-3)
    assert set(res["per_subject"]) == {"subject_000", "subject_001"}
    rows = list(csv.DictReader((out.parent / "oracle.frames.csv").open()))
    assert len(rows) == 4 and all(r["image_psnr"] == "inf" for r in rows)
    assert "backbone=alex" in stdout


def test_noisy_png_predictions_score_sensibly(ds, noisy, tmp_path, capsys):
    out = tmp_path / "noisy.json"
    code, _, err = _run([noisy, "--dataset", ds, "--out", out, "--backbone", "vgg"], capsys)
    assert code == 0, err
    res = json.loads(out.read_text())
    ov = res["overall"]
    assert 20 < ov["image_psnr"]["mean"] < 60 and ov["image_psnr"]["n_infinite"] == 0
    assert 0 < ov["image_lpips"]["mean"] < 0.5 and 0.5 < ov["image_ssim"]["mean"] < 1
    assert 0 < ov["normal_deg"]["mean"] < 20
    assert ov["image_psnr"]["std"] > 0
    assert res["kind"] == "method" and res["convention"]["backbone"] == "vgg"
    assert "lpips_vgg_v0.1" in res["weights"]
    # per-subject means are the means of that subject's CSV rows
    rows = [r for r in csv.DictReader(out.with_name("noisy.frames.csv").open()) if r["subject"] == "subject_001"]
    want = np.mean([float(r["image_lpips"]) for r in rows])
    assert res["per_subject"]["subject_001"]["metrics"]["image_lpips"]["mean"] == pytest.approx(want, abs=1e-12)


def test_png_normals_decode_as_the_dataset_encodes(ds, tmp_path):
    pred = make_predictions(ds, tmp_path / "p", fmt="png", layers=("image", "normal"))
    res, rows, cols = Evaluator(EvalOptions(metrics=("normal",), progress=False)).evaluate(pred, ds)
    # 8-bit quantisation of unit normals: well under a degree
    assert 0 < res["overall"]["normal_deg"]["mean"] < 0.5


def test_help_explains_every_flag():
    text = build_parser().format_help()
    for flag in ("--dataset", "--protocol", "--out", "--backbone", "--region", "--align-albedo",
                 "--allow-incomplete", "--metrics", "--batch-size", "--cache-dir", "--background",
                 "--albedo-space", "--kind", "--flip-ppd", "--workers", "--preload-mb"):
        assert flag in text


# --------------------------------------------------------------------------------------------- conventions
def test_region_geometry():
    assert margin_for(720, 1280) == 50 and margin_for(512, 512) == 36 and margin_for(64, 64) == 4
    mask = np.zeros((512, 512), np.uint8)
    mask[200:300, 240:260] = 255
    r = compute_region(mask, Convention(region="default"))
    assert (r.y0, r.y1, r.x0, r.x1) == (164, 336, 204, 296)
    r = compute_region(mask, Convention(region="mask"))
    assert (r.y0, r.y1) == (200, 300) and r.x1 - r.x0 == MIN_CROP  # grown to the minimum crop
    assert r.metric_mask.sum() == 100 * 20
    r = compute_region(mask, Convention(region="full"))
    assert (r.y0, r.y1, r.x0, r.x1) == (0, 512, 0, 512) and r.alpha is None
    assert compute_region(np.zeros((64, 64), np.uint8), Convention()).empty
    mask[:] = 127  # below "inside" threshold (coverage > 0.5 means >= 128)
    assert compute_region(mask, Convention()).empty


def test_region_changes_the_score_and_is_recorded(ds, noisy):
    vals = {}
    for region in ("default", "full", "mask"):
        ev = Evaluator(EvalOptions(convention=Convention(region=region), metrics=("psnr", "ssim"), progress=False))
        res, _, _ = ev.evaluate(noisy, ds)
        assert res["convention"]["region"] == region
        vals[region] = res["overall"]["image_psnr"]["mean"]
    assert len(set(vals.values())) == 3


def test_albedo_alignment_is_reported_beside_the_raw_score(ds, tmp_path):
    pred = make_predictions(ds, tmp_path / "half", layers=("image", "albedo"), albedo_scale=0.5)
    ev = Evaluator(EvalOptions(convention=Convention(align_albedo=True), metrics=("psnr", "ssim"), progress=False))
    res, rows, _ = ev.evaluate(pred, ds)
    ov = res["overall"]
    assert math.isfinite(ov["albedo_psnr"]["mean"]) and ov["albedo_ssim"]["mean"] < 1
    assert ov["albedo_aligned_psnr"]["mean"] == "inf"  # 0.5 exactly undone by the least-squares scale 2
    assert rows[0]["albedo_scale"] == pytest.approx([2.0, 2.0, 2.0])
    res2, _, _ = Evaluator(EvalOptions(metrics=("psnr",), progress=False)).evaluate(pred, ds)
    assert "albedo_aligned_psnr" not in res2["overall"]


def test_empty_mask_frame_is_undefined_not_averaged(tmp_path):
    ds = make_dataset(tmp_path / "ds", empty_mask=("subject_001", 1))
    pred = make_predictions(ds, tmp_path / "p", noise=0.05, layers=("image", "normal"))
    res, rows, _ = Evaluator(EvalOptions(metrics=("psnr", "ssim", "normal"), progress=False)).evaluate(pred, ds)
    assert res["n_frames_empty_mask"] == 1
    assert res["overall"]["image_psnr"]["n"] == 3 and res["overall"]["image_psnr"]["n_undefined"] == 1
    assert res["overall"]["normal_deg"]["n_undefined"] == 1
    row = [r for r in rows if r["subject"] == "subject_001" and r["frame"] == 1][0]
    assert row["image_psnr"] is None and row["normal_deg"] is None
    full = Evaluator(EvalOptions(convention=Convention(region="full"), metrics=("psnr",), progress=False))
    res_full, _, _ = full.evaluate(pred, ds)
    assert res_full["overall"]["image_psnr"]["n"] == 4


# --------------------------------------------------------------------------------------------- speed machinery
def test_ground_truth_features_are_cached_in_memory_and_on_disk(ds, noisy, oracle, tmp_path):
    opts = dict(metrics=("lpips", "dists"), progress=False)
    ev = Evaluator(EvalOptions(cache_dir=tmp_path / "cache", **opts))
    r1, rows1, _ = ev.evaluate(noisy, ds)
    assert r1["gt_feature_cache"]["misses"] > 0
    r2, rows2, _ = ev.evaluate(oracle, ds)  # another method, same ground truth: no GT forward pass
    assert r2["gt_feature_cache"]["misses"] == 0 and r2["gt_feature_cache"]["hits"] > 0
    ev2 = Evaluator(EvalOptions(cache_dir=tmp_path / "cache", **opts))  # a new process would do the same
    r3, rows3, _ = ev2.evaluate(noisy, ds)
    assert r3["gt_feature_cache"]["misses"] == 0 and r3["gt_feature_cache"]["disk_hits"] > 0
    assert r3["overall"] == r1["overall"]
    # batch size does not change scores
    r4, _, _ = Evaluator(EvalOptions(batch_size=1, **opts)).evaluate(noisy, ds)
    for k in r1["overall"]:
        assert r4["overall"][k]["mean"] == pytest.approx(r1["overall"][k]["mean"], abs=1e-6)


# --------------------------------------------------------------------------------------------- refused inputs
def _copy(oracle: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "pred"
    shutil.copytree(oracle, dst)
    return dst


def _png16(path: Path, h: int, w: int) -> None:
    raw = b"".join(b"\x00" + np.full((w, 3), 30000, ">u2").tobytes() for _ in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def _break(kind: str, pred: Path) -> Path:
    """Damage a prediction set one way; return the file the error must name."""
    d = pred / FRAME_DIR
    img = d / "frame_000001_image.exr"
    if kind == "missing":
        img.unlink()
        return img
    if kind == "extra":
        p = d / "frame_000007_image.exr"
        shutil.copyfile(img, p)
        return p
    if kind == "unexpected-file":
        p = d / "notes.txt"
        p.write_text("hi")
        return p
    if kind == "both-formats":
        write_png(d / "frame_000001_image.png", np.zeros((64, 64, 3), np.uint8))
        return d / "frame_000001_image.png"
    if kind == "resolution":
        write_exr(img, np.zeros((32, 64, 3), np.float32))
        return img
    if kind in ("nan", "inf"):
        a = read_exr(img)
        a[5, 5, 0] = np.nan if kind == "nan" else np.inf
        write_exr(img, a)
        return img
    if kind == "channels-exr":
        write_exr(img, np.zeros((64, 64), np.float32))
        return img
    if kind == "channels-png":
        img.unlink()
        p = d / "frame_000001_image.png"
        write_png(p, np.zeros((64, 64), np.uint8))
        return p
    if kind == "16bit-png":
        img.unlink()
        p = d / "frame_000001_image.png"
        _png16(p, 64, 64)
        return p
    if kind == "corrupt-exr":
        img.write_bytes(b"not an exr at all" * 10)
        return img
    if kind == "corrupt-png":
        img.unlink()
        p = d / "frame_000001_image.png"
        p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
        return p
    if kind == "missing-normal":
        p = d / "frame_000000_normal.exr"
        p.unlink()
        return d / "frame_000000_normal.exr"
    if kind == "nan-normal":
        p = d / "frame_000000_normal.exr"
        a = read_exr(p)
        a[30, 30] = np.nan
        write_exr(p, a)
        return p
    if kind == "extra-subject":
        p = pred / "subject_999"
        (p / "protocol_a" / "test").mkdir(parents=True)
        return p
    raise AssertionError(kind)


BROKEN = {
    "missing": "missing frame", "extra": "extra frame", "unexpected-file": "unexpected file",
    "both-formats": "layer given twice", "resolution": "resolution 64x32", "nan": "NaN or Inf",
    "inf": "NaN or Inf", "channels-exr": "1 channel", "channels-png": "greyscale", "16bit-png": "16-bit PNG",
    "corrupt-exr": "not a readable EXR", "corrupt-png": "PNG", "missing-normal": "missing normal",
    "nan-normal": "NaN or Inf", "extra-subject": "unexpected folder",
}


@pytest.mark.parametrize("kind", sorted(BROKEN))
def test_bad_prediction_sets_are_refused_naming_the_file(kind, ds, oracle, tmp_path, capsys):
    pred = _copy(oracle, tmp_path)
    culprit = _break(kind, pred)
    out = tmp_path / "r.json"
    code, _, err = _run([pred, "--dataset", ds, "--out", out, "--metrics", "psnr,normal"], capsys)
    assert code == 2, err
    assert str(culprit) in err and BROKEN[kind] in err, err
    assert not out.exists()


def test_allow_incomplete_marks_the_result(ds, oracle, tmp_path, capsys):
    pred = _copy(oracle, tmp_path)
    culprit = _break("missing", pred)
    out = tmp_path / "r.json"
    code, stdout, err = _run([pred, "--dataset", ds, "--out", out, "--metrics", "psnr", "--allow-incomplete"],
                             capsys)
    assert code == 0, err
    res = json.loads(out.read_text())
    assert res["complete"] is False and res["n_frames_evaluated"] == 3
    assert any(str(culprit) in m for m in res["missing"])
    assert "INCOMPLETE" in stdout
    # a corrupt file is still refused with --allow-incomplete
    _break("corrupt-exr", pred) if (pred / FRAME_DIR / "frame_000001_image.exr").exists() else None
    (pred / FRAME_DIR / "frame_000000_image.exr").write_bytes(b"garbage")
    code, _, err = _run([pred, "--dataset", ds, "--out", out, "--metrics", "psnr", "--allow-incomplete"], capsys)
    assert code == 2 and "frame_000000_image.exr" in err


def test_bad_arguments(ds, oracle, tmp_path, capsys):
    code, _, err = _run([oracle, "--dataset", ds, "--out", tmp_path / "r.json", "--metrics", "psnr,bogus"], capsys)
    assert code == 2 and "bogus" in err
    code, _, err = _run([oracle, "--dataset", tmp_path, "--out", tmp_path / "r.json"], capsys)
    assert code == 2 and "manifest" in err
    code, _, err = _run([oracle, "--dataset", ds, "--protocol", "b", "--out", tmp_path / "r.json"], capsys)
    assert code == 2 and "protocol_b" in err


def test_method_json_kind_is_checked(ds, oracle, tmp_path, capsys):
    pred = _copy(oracle, tmp_path)
    (pred / "method.json").write_text(json.dumps({"name": "x", "kind": "oracle-ish"}))
    code, _, err = _run([pred, "--dataset", ds, "--out", tmp_path / "r.json", "--metrics", "psnr"], capsys)
    assert code == 2 and "method.json" in err and "kind" in err


def test_whole_set_is_checked_before_any_metric(ds, oracle, tmp_path, capsys, monkeypatch):
    """Bad files in the first and the last frame: both reported at once, before a single frame is evaluated."""
    pred = _copy(oracle, tmp_path)
    last = pred / "subject_001/protocol_a/test/frame_000001_image.exr"
    a = read_exr(last)
    a[40, 7, 1] = np.inf
    write_exr(last, a)
    first = pred / FRAME_DIR / "frame_000000_albedo.exr"
    write_exr(first, np.zeros((64, 48, 3), np.float32))

    def no_metrics(*_a, **_k):
        raise AssertionError("a frame was evaluated before the prediction set was checked")

    monkeypatch.setattr(Evaluator, "_prepare", no_metrics)
    out = tmp_path / "r.json"
    code, _, err = _run([pred, "--dataset", ds, "--out", out], capsys)
    assert code == 2, err
    assert f"{last}: 1 pixel(s) with NaN or Inf (first at x=7, y=40)" in err  # the file, the pixel, the fix
    assert "write finite values" in err
    assert f"{first}: resolution 48x64" in err and "write it at 64x64" in err
    assert "2 problem(s)" in err  # every bad file at once, header and pixel problems alike
    assert not out.exists() and not out.with_name("r.frames.csv").exists()


def test_rows_do_not_depend_on_workers_prefetch_or_preload(ds, noisy):
    opts = dict(metrics=("lpips", "ssim", "psnr", "flip", "normal"), progress=False)
    _, base, _ = Evaluator(EvalOptions(**opts)).evaluate(noisy, ds)
    assert [(r["subject"], r["frame"]) for r in base] == [(s, f) for s in ("subject_000", "subject_001")
                                                          for f in (0, 1)]  # dataset order
    for kw in (dict(workers=1, prefetch=1, preload_mb=0, overlap=False), dict(workers=3, prefetch=7, overlap=True)):
        # (batch size: see the cache test; oneDNN kernels vary with N)
        _, rows, _ = Evaluator(EvalOptions(**opts, **kw)).evaluate(noisy, ds)
        assert rows == base, kw


def test_networks_see_only_the_evaluated_region(tmp_path, monkeypatch):
    """Default region: the networks run on the person's dilated box, not on the frame."""
    ds = make_dataset(tmp_path / "ds", size=160, subjects=("subject_000",), frames=(0,))
    pred = make_predictions(ds, tmp_path / "p", noise=0.05, layers=("image",))
    ev = Evaluator(EvalOptions(metrics=("lpips",), progress=False))
    net = get_lpips_net("alex")  # the one the public `lpips` functions run
    shapes = []
    real = net.features
    monkeypatch.setattr(net, "features", lambda x: shapes.append(tuple(x.shape)) or real(x))
    ev.evaluate(pred, ds)
    mask = read_png(ds / FRAME_DIR / "frame_000000_mask.png")
    r = compute_region(mask, Convention())
    assert shapes == [(1, 3, r.y1 - r.y0, r.x1 - r.x0)] * 2 and r.x1 - r.x0 < 160  # ground truth, prediction
    # the networks and their weights are loaded once per process
    loaded = get_lpips_net.cache_info().currsize
    Evaluator(EvalOptions(metrics=("lpips",), progress=False))
    assert get_lpips_net.cache_info().currsize == loaded and get_lpips_net("alex") is net


def test_progress_bar_on_long_runs(ds, noisy, capsys):
    Evaluator(EvalOptions(metrics=("psnr",), progress=True)).evaluate(noisy, ds)
    err = capsys.readouterr().err
    assert "rh-eval noisy" in err and "4/4" in err and "frame" in err


def test_pipeline_edge_cases_raise_no_warning(tmp_path):
    ds = make_dataset(tmp_path / "ds", empty_mask=("subject_001", 1))
    pred = make_predictions(ds, tmp_path / "p")  # the ground truth itself, and one empty mask
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res, _, _ = Evaluator(EvalOptions(progress=False)).evaluate(pred, ds)
    ov = res["overall"]
    assert ov["image_psnr"]["mean"] == "inf" and ov["image_psnr"]["n_undefined"] == 1
    assert ov["image_lpips"]["mean"] == 0.0 and ov["normal_deg"]["mean"] == 0.0


def test_outputs_record_manifest_versions_and_counts(ds, noisy, tmp_path, capsys):
    out = tmp_path / "n.json"
    code, _, err = _run([noisy, "--dataset", ds, "--out", out, "--metrics", "psnr,lpips"], capsys)
    assert code == 0, err
    res = json.loads(out.read_text())
    from rh_common.imageio import sha256_file
    assert res["dataset"]["manifest_sha256"] == sha256_file(ds / "manifest.json")
    assert {"rh_eval", "torch", "numpy", "scikit-image", "flip-evaluator", "lpips"} <= set(res["versions"])
    assert res["n_frames_evaluated"] == 4 and res["complete"] is True
    for block in [res["overall"]] + [s["metrics"] for s in res["per_subject"].values()]:
        for col in ("image_psnr", "image_lpips"):
            assert {"mean", "std", "n", "n_undefined"} <= set(block[col])


# --------------------------------------------------------------------------------------------- FLIP ppd
def test_flip_ppd_is_a_recorded_convention(ds, noisy, tmp_path, capsys):
    vals = {}
    for ppd in (None, "30"):
        out = tmp_path / f"f{ppd}.json"
        extra = ["--flip-ppd", ppd] if ppd else []
        code, stdout, err = _run([noisy, "--dataset", ds, "--out", out, "--metrics", "flip", *extra], capsys)
        assert code == 0, err
        res = json.loads(out.read_text())
        want = 30.0 if ppd else 67.02064514160156
        assert res["convention"]["flip_ppd"] == want and res["flip_ppd"] == want
        assert f"flip_ppd={want:.6g}" in stdout
        vals[ppd] = res["overall"]["image_flip"]["mean"]
    assert vals[None] != vals["30"]  # the viewing distance changes what FLIP sees


@pytest.mark.parametrize("bad", ["0", "-67", "nan", "inf", "sixty"])
def test_flip_ppd_is_validated(bad, ds, oracle, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main([str(oracle), "--dataset", str(ds), "--out", str(tmp_path / "r.json"), "--flip-ppd", bad])
    assert exc.value.code == 2 and "--flip-ppd" in capsys.readouterr().err
    with pytest.raises(ValueError, match="flip_ppd"):
        Convention(flip_ppd=float(bad) if bad != "sixty" else "sixty")
