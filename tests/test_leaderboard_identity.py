"""rh-eval records the content identity of the split it scored, and rh-leaderboard combines results on it: the
same identity combines, another one is refused unless an `rh-verify --against` record finds the two datasets
within tolerance, and then the rows are marked ≈ and the tables say why."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from rh_common import layout
from rh_common.imageio import read_exr, read_json, read_png
from rh_dataset.verify import main as verify_main
from rh_eval.cli import main as eval_main
from rh_eval.leaderboard import main as lb_main
from test_eval_fake import make_dataset, make_predictions


def _perturb_image(src, dst, delta: float):
    """A copy of dataset `src` whose first test frame's image is off by `delta`, rewritten by the real writer."""
    shutil.copytree(src, dst)
    jp = next(layout.iter_frame_jsons(dst, "a", "test"))
    rec = read_json(jp)
    d, i = jp.parent, rec["index"]
    layers = {"image": read_exr(d / layout.layer_file_name(i, "image", "exr")) + np.float32(delta),
              "mask": read_png(d / layout.layer_file_name(i, "mask", "png")).astype(np.float32) / 255.0,
              "albedo": read_exr(d / layout.layer_file_name(i, "albedo", "exr")),
              "normal": read_exr(d / layout.layer_file_name(i, "normal", "exr"))}
    layout.write_frame(d, i, layers, {k: v for k, v in rec.items() if k not in ("files", "format", "index")})
    layout.write_manifest(dst)
    return dst


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("lbid")
    a = make_dataset(root / "a")
    b = _perturb_image(a, root / "b", 1e-6)     # another machine's rounding: within tolerance
    c = _perturb_image(a, root / "c", 1e-3)     # a difference a method could see
    pred = make_predictions(a, root / "pred", name="m", noise=0.02)
    res = {}
    for name, ds in (("a", a), ("b", b), ("c", c)):
        res[name] = root / f"res_{name}.json"
        assert eval_main([str(pred), "--dataset", str(ds), "--out", str(res[name]), "--no-progress",
                          "--metrics", "psnr"]) == 0
    return root, {"a": a, "b": b, "c": c}, res


def test_rh_eval_records_the_scored_splits_identity(setup):
    root, ds, res = setup
    for name in "abc":
        r = json.loads(res[name].read_text())
        assert r["dataset"]["content_identity"] == layout.read_identity(ds[name])["splits"]["protocol_a/test"]["digest"]
    ids = {json.loads(res[n].read_text())["dataset"]["content_identity"] for n in "abc"}
    assert len(ids) == 3


def test_leaderboard_combines_on_identity_and_on_a_tolerance_record(setup, tmp_path, capsys):
    root, ds, res = setup
    # The same dataset copied elsewhere (another manifest path, same identity): combined.
    same = tmp_path / "same.json"
    r = json.loads(res["a"].read_text())
    r["method"]["name"] = "m2"
    r["dataset"]["manifest_sha256"] = "0" * 64  # e.g. other EXR encoder bytes: the identity decides
    same.write_text(json.dumps(r))
    assert lb_main([str(res["a"]), str(same), "--out", str(tmp_path / "lb0")]) == 0
    # Another identity without a comparison record: refused, saying how to compare.
    assert lb_main([str(res["a"]), str(res["b"]), "--out", str(tmp_path / "lb1")]) == 2
    err = capsys.readouterr().err
    assert "content identity" in err and "--comparison" in err
    # With rh-verify --against's record: combined, marked ≈, and the tables say within what.
    rec = tmp_path / "ab.json"
    assert verify_main([str(ds["a"]), "--against", str(ds["b"]), "--record", str(rec), "--no-progress"]) == 0
    capsys.readouterr()
    assert lb_main([str(res["a"]), str(res["b"]), "--out", str(tmp_path / "lb2"), "--comparison", str(rec)]) == 0
    md = (tmp_path / "lb2" / "leaderboard.md").read_text()
    assert "agrees with" in md and "only within rounding" in md and "lowest layer PSNR" in md
    rows = [l for l in md.splitlines() if l.startswith("| m")]
    assert sorted(rw.split("|")[1].strip() for rw in rows) == ["m (res_a.json)", "m (res_b.json) ≈"]
    html = (tmp_path / "lb2" / "index.html").read_text()
    assert "only within rounding" in html and "m (res_b.json) ≈" in html
    # A record that found them different: refused with that reason.
    rec_c = tmp_path / "ac.json"
    assert verify_main([str(ds["a"]), "--against", str(ds["c"]), "--record", str(rec_c), "--no-progress"]) == 1
    capsys.readouterr()
    assert lb_main([str(res["a"]), str(res["c"]), "--out", str(tmp_path / "lb3"), "--comparison", str(rec_c)]) == 2
    assert "NOT the same benchmark" in capsys.readouterr().err
    # A missing or foreign comparison file: one line, exit 2.
    assert lb_main([str(res["a"]), "--out", str(tmp_path / "lb4"), "--comparison", str(tmp_path / "no.json")]) == 2
    assert lb_main([str(res["a"]), "--out", str(tmp_path / "lb4"), "--comparison", str(res["a"])]) == 2
    assert "rh-verify A --against B" in capsys.readouterr().err


def test_results_without_identity_fall_back_to_the_manifest(setup, tmp_path, capsys):
    root, ds, res = setup
    old = []
    for n in "ab":
        r = json.loads(res[n].read_text())
        del r["dataset"]["content_identity"]
        old.append(tmp_path / f"old_{n}.json")
        old[-1].write_text(json.dumps(r))
    assert lb_main([str(old[0]), str(old[1]), "--out", str(tmp_path / "x")]) == 2
    assert "manifest sha256" in capsys.readouterr().err
    assert lb_main([str(old[0]), str(res["a"]), "--out", str(tmp_path / "y")]) == 0
