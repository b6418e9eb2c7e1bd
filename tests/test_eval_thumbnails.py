"""rh-eval's pictures (`rh_eval.thumbnails`): the tiles are the crops the metrics see, the frame selection is the
same for every method and run, the files are bitwise reproducible and small, and an identical prediction has a
black error map."""
from __future__ import annotations

import json
import random
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from rh_eval.cli import main as eval_main
from rh_eval.conventions import Convention
from rh_eval.dataset_io import load_dataset, scan_predictions
from rh_eval.scoring import prepare_frame, read_frame
from rh_common.imageio import write_webp
from rh_eval.thumbnails import (PER_SUBJECT, TILE_PX, WEBP_QUALITY, _colourise, frame_crops, seeded_rank, select_extremes,
                                select_fixed)
from test_eval_fake import make_dataset, make_predictions

FRAMES = tuple(range(6))  # more frames per subject than the fixed selection takes


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("thumbs") / "ds", size=256, frames=FRAMES)


def _eval(pred: Path, ds: Path, out: Path, *extra) -> dict:
    assert eval_main([str(pred), "--dataset", str(ds), "--out", str(out), "--no-progress",
                      "--metrics", "psnr,ssim,normal", *extra]) == 0
    return json.loads(out.read_text())


@pytest.mark.parametrize("region", ["default", "full", "mask"])
def test_tiles_are_cut_from_the_crops_the_metrics_see(ds, tmp_path, region):
    pred = make_predictions(ds, tmp_path / "p", noise=0.05, fmt="png")
    conv = Convention(region=region)
    for pf in scan_predictions(pred, load_dataset(ds, "a")).frames[:2]:
        fp, fg = read_frame(pf)
        _, pairs = prepare_frame(fp, fg, conv, ("lpips",))
        crops = frame_crops(fp, fg, conv)
        for pair in pairs:  # the networks' float32 inputs are the same crops, composited the same way
            np.testing.assert_array_equal(np.float32(crops[pair.layer]), pair.pred)
            np.testing.assert_array_equal(np.float32(crops[pair.layer + "_gt"]), pair.target)
        assert {p.layer for p in pairs} == {"image", "albedo"}


def test_fixed_selection_depends_on_frame_names_only():
    class F:
        def __init__(self, s, i):
            self.subject, self.index, self.key = s, i, f"{s}/frame_{i:06d}"

    frames = [F(s, i) for s in ("subject_000", "subject_001", "subject_002") for i in range(10)]
    keys = select_fixed(frames)
    assert len(keys) == 3 * PER_SUBJECT
    shuffled = frames[:]
    random.Random(0).shuffle(shuffled)
    assert select_fixed(shuffled) == keys  # order of the split: irrelevant
    assert select_fixed([f for f in frames if f.subject == "subject_001"]) == {k for k in keys if "_001/" in k}
    for s in ("subject_000",):  # the first PER_SUBJECT by the documented hash
        want = sorted(range(10), key=lambda i: seeded_rank(s, i))[:PER_SUBJECT]
        assert {k for k in keys if k.startswith(s)} == {f"{s}/frame_{i:06d}" for i in want}
    assert len(select_fixed(frames[:2])) == 2  # fewer frames than PER_SUBJECT: all of them


def test_extremes():
    rows = [{"image_lpips": v} for v in (0.3, None, 0.1, 0.2, 0.5)]
    keys = list("abcde")
    assert select_extremes(rows, keys, ["image_lpips"]) == {"best": "c", "median": "d", "worst": "e"}
    rows = [{"image_psnr": v} for v in (20.0, float("inf"), 30.0)]
    assert select_extremes(rows, list("abc"), ["image_psnr"]) == {"best": "b", "median": "c", "worst": "a"}
    assert select_extremes([{"image_psnr": None}], ["a"], ["image_psnr"]) == {}


def test_rh_eval_writes_the_selection_small_and_reproducibly(ds, tmp_path):
    noisy = make_predictions(ds, tmp_path / "noisy", name="noisy", noise=0.08)
    res = _eval(noisy, ds, tmp_path / "r" / "noisy.json")
    rec = res["thumbnails"]
    folder = tmp_path / "r" / rec["dir"]
    assert rec["dir"] == "noisy.thumbs" and (folder / "index.json").is_file()
    index = json.loads((folder / "index.json").read_text())
    names = {f["name"] for f in index["frames"]}
    fixed = {f["name"] for f in index["frames"] if "fixed" in f["roles"]}
    assert len(fixed) == 2 * PER_SUBJECT  # 2 subjects
    roles = {r: f["name"] for f in index["frames"] for r in f["roles"] if r != "fixed"}
    assert set(roles) == {"best", "median", "worst"}
    psnr = {f"{r['subject']}/frame_{int(r['frame']):06d}": float(r["image_psnr"])
            for r in _csv(tmp_path / "r" / "noisy.frames.csv")}
    assert psnr[roles["best"]] == max(psnr.values()) and psnr[roles["worst"]] == min(psnr.values())
    for f in index["frames"]:
        assert set(f["tiles"]) == {f"{layer}{s}" for layer in ("image", "albedo", "normal")
                                   for s in ("", "_gt", "_err")}
        assert f["scores"]["image_psnr"] == pytest.approx(psnr[f["name"]], abs=0)
        for rel in f["tiles"].values():
            with Image.open(folder / rel) as im:
                assert im.format == "WEBP" and max(im.size) == TILE_PX  # 256 px frames: the crop is shrunk
    total = sum(p.stat().st_size for p in folder.rglob("*.webp"))
    assert total == index["tile_bytes"] == rec["tile_bytes"]
    assert total < 9 * 6 * len(names) * 1024  # about 6 KB a tile at most (measured: docs/EVALUATION.md)
    # another method, another run: the same fixed frames; the same inputs: the same bytes
    other = make_predictions(ds, tmp_path / "other", name="other", noise=0.02, seed=5)
    _eval(other, ds, tmp_path / "r2" / "other.json")
    index2 = json.loads((tmp_path / "r2" / "other.thumbs" / "index.json").read_text())
    assert {f["name"] for f in index2["frames"] if "fixed" in f["roles"]} == fixed
    _eval(noisy, ds, tmp_path / "r3" / "noisy.json")
    again = tmp_path / "r3" / "noisy.thumbs"
    assert sorted(p.relative_to(again) for p in again.rglob("*")) == sorted(p.relative_to(folder)
                                                                            for p in folder.rglob("*"))
    for p in folder.rglob("*.webp"):
        assert p.read_bytes() == (again / p.relative_to(folder)).read_bytes()
    # rerunning into the same place replaces the folder whole, leaving no temporary folder behind
    _eval(noisy, ds, tmp_path / "r3" / "noisy.json")
    assert sorted(x.name for x in (tmp_path / "r3").iterdir()) == ["noisy.frames.csv", "noisy.json", "noisy.thumbs"]


def _csv(path: Path) -> list[dict]:
    import csv

    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_identical_prediction_has_black_error_maps(ds, tmp_path):
    oracle = make_predictions(ds, tmp_path / "oracle", name="oracle")
    _eval(oracle, ds, tmp_path / "oracle.json")
    folder = tmp_path / "oracle.thumbs"
    black = _colourise(np.zeros((1, 1)))[0, 0]
    for f in json.loads((folder / "index.json").read_text())["frames"]:
        for layer in ("image", "albedo", "normal"):
            err = folder / f["tiles"][layer + "_err"]
            with Image.open(err) as im:
                size = im.size
            write_webp(tmp_path / "black.webp", np.broadcast_to(black.astype(np.uint8), (size[1], size[0], 3)),
                       quality=WEBP_QUALITY)
            assert err.read_bytes() == (tmp_path / "black.webp").read_bytes()  # FLIP 0 / 0 degrees everywhere
            a = np.asarray(Image.open(folder / f["tiles"][layer]).convert("RGB"), dtype=int)
            b = np.asarray(Image.open(folder / f["tiles"][layer + "_gt"]).convert("RGB"), dtype=int)
            assert np.array_equal(a, b)  # the same pixels encode to the same bytes


def test_no_thumbnails(ds, tmp_path):
    pred = make_predictions(ds, tmp_path / "p", name="p", noise=0.02)
    res = _eval(pred, ds, tmp_path / "p.json", "--no-thumbnails")
    assert "thumbnails" not in res and not (tmp_path / "p.thumbs").exists()
