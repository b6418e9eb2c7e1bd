"""Scoring a split other than test (`rh-eval --split`, `rana-oracle --split`, rh-leaderboard's tables per split) on
the tiny fake dataset with a test and an olat split."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rana.oracle import main as oracle_main
from rh_common import layout
from rh_common.imageio import read_exr, read_png
from rh_eval.cli import main as eval_main
from rh_eval.leaderboard import build_markdown, load_results
from test_eval_fake import make_dataset, make_predictions

METRICS = "psnr,ssim"  # no network: the split's plumbing is under test, not the metrics


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("ds") / "data", splits=("test", "olat"), with_light=True)


def _eval(pred: Path, ds: Path, out: Path, *extra: str) -> int:
    return eval_main([str(pred), "--dataset", str(ds), "--out", str(out), "--metrics", METRICS, "--no-progress",
                      "--no-thumbnails", *extra])


def test_splits_of_lists_the_splits_with_frames(ds):
    assert layout.splits_of(ds, "a") == ["olat", "test"]
    assert layout.prediction_file("p", "subject_000", "a", 3, "image", split="olat") == \
        Path("p/subject_000/protocol_a/olat/frame_000003_image.exr")
    assert layout.prediction_dir("p", "subject_000", "a") == Path("p/subject_000/protocol_a/test")


def test_olat_split_is_scored_and_recorded(ds, tmp_path):
    pred = make_predictions(ds, tmp_path / "gt_olat", split="olat", kind="bound")
    assert _eval(pred, ds, tmp_path / "olat.json", "--split", "olat") == 0
    r = json.loads((tmp_path / "olat.json").read_text())
    assert r["dataset"]["split"] == "olat" and r["complete"] and r["n_frames_evaluated"] == 4
    assert r["dataset"]["content_identity"] == layout.split_identity(ds, "a", "olat")
    assert r["dataset"]["content_identity"] != layout.split_identity(ds, "a", "test")
    assert r["overall"]["image_psnr"]["mean"] == "inf"  # the ground truth itself
    # the default is still the test split, and the olat predictions are not a test prediction set
    assert _eval(pred, ds, tmp_path / "test.json") == 2
    # one folder may hold both splits' predictions: each run reads its own split's folders only
    make_predictions(ds, pred, split="test", kind="bound")
    assert _eval(pred, ds, tmp_path / "test.json") == 0 and _eval(pred, ds, tmp_path / "olat.json", "--split",
                                                                  "olat") == 0
    assert json.loads((tmp_path / "test.json").read_text())["dataset"]["split"] == "test"


def test_a_split_the_dataset_lacks_is_one_line_listing_its_splits(ds, tmp_path, capsys):
    pred = make_predictions(ds, tmp_path / "gt", split="test")
    assert _eval(pred, ds, tmp_path / "r.json", "--split", "olta") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'olta'" in err and "it has: olat, test" in err
    assert oracle_main(["--dataset", str(ds), "--split", "olta", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "it has: olat, test" in err


def test_oracle_writes_the_olat_split_and_is_exact_for_order_one_light(ds, tmp_path):
    # The fake's shading 2 (0.3 + 0.7 n_z + 0.2 n_y) is linear in n, so order-2 SH holds it exactly: inside the
    # person the bound is the ground-truth image up to the fake's +-0.01 noise.
    out = tmp_path / "oracle"
    assert oracle_main(["--dataset", str(ds), "--split", "olat", "--out", str(out)]) == 0
    folder = layout.split_dir(ds, "subject_000", "a", "olat")
    gt = read_exr(folder / layout.layer_file_name(1, "image", "exr"))
    albedo = read_exr(folder / layout.layer_file_name(1, "albedo", "exr"))
    normal = read_exr(folder / layout.layer_file_name(1, "normal", "exr"))
    pred = read_exr(layout.prediction_file(out, "subject_000", "a", 1, "image", split="olat"))
    inside = np.linalg.norm(normal, axis=-1) > 0.999
    expect = albedo * 2.0 * (0.3 + 0.7 * normal[..., 2:3] + 0.2 * normal[..., 1:2])
    assert np.abs(pred - expect)[inside].max() < 1e-5
    # opaque pixels: the noise (0.01) plus at most 0.5/255 of the environment blended into an 8-bit-opaque edge
    opaque = read_png(folder / layout.layer_file_name(1, "mask", "png")) == 255
    assert np.abs(pred - gt)[opaque].max() <= 0.01 + 2.0 * 0.5 / 255
    assert np.array_equal(pred[~np.any(normal != 0, axis=-1)], gt[~np.any(normal != 0, axis=-1)])
    assert not (out / "subject_000" / "protocol_a" / "test").exists()


def test_leaderboard_keeps_splits_in_their_own_tables(ds, tmp_path):
    a = make_predictions(ds, tmp_path / "t", split="test", kind="bound")
    b = make_predictions(ds, tmp_path / "o", split="olat", kind="bound")
    assert _eval(a, ds, tmp_path / "test.json") == 0
    assert _eval(b, ds, tmp_path / "olat.json", "--split", "olat") == 0
    entries, problems = load_results([tmp_path / "test.json", tmp_path / "olat.json"])
    assert problems == []  # each split's identity is checked against its own first result, not the other split's
    md = build_markdown(entries)
    assert "## Convention `rana`\n" in md and "## Convention `rana`, split `olat`" in md
    assert "olat split content identity" in md and "test split content identity" in md
    # one row per method in the side-by-side table, its test and olat columns next to each other
    side = md.split("## Side by side")[1]
    assert "(rana-olat)" in side and side.count("| oracle") == 1
