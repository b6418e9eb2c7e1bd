"""bench/coverage_split.py splits rh-eval's normal and albedo errors into the predicted pixels and missing coverage."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from rh_common.imageio import read_exr, write_exr
from test_eval_fake import make_dataset, make_predictions

BENCH = Path(__file__).resolve().parents[1] / "bench" / "coverage_split.py"


@pytest.fixture(scope="module")
def split():
    spec = importlib.util.spec_from_file_location("coverage_split", BENCH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod.split


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """The ground truth, and the ground truth with no normal and no albedo on the left half of every frame."""
    root = tmp_path_factory.mktemp("cov")
    ds = make_dataset(root / "data")
    exact = make_predictions(ds, root / "exact", name="exact")
    half = make_predictions(ds, root / "half", name="half")
    missing = []
    for layer in ("normal", "albedo"):
        for f in sorted(half.rglob(f"*_{layer}.exr")):
            v = read_exr(f)
            person = np.any(v != 0, axis=-1)
            v[:, : v.shape[1] // 2] = 0
            if layer == "normal":
                missing.append(1 - np.any(v != 0, axis=-1).sum() / person.sum())
            write_exr(f, v)
    return ds, exact, half, float(np.mean(missing))


def test_uncovered_normals_cost_90_degrees_and_are_reported_apart(split, case):
    ds, exact, half, missing = case
    rows = {r["name"]: r for r in split([exact, half], ds, "a")}
    assert rows["exact"]["total"] == 0.0 and rows["exact"]["missing"] == 0.0
    assert rows["half"]["where_predicted"] == pytest.approx(0.0, abs=1e-3)
    assert rows["half"]["where_all_predict"] == pytest.approx(0.0, abs=1e-3)
    assert rows["half"]["missing"] == pytest.approx(missing, abs=1e-6)
    assert 0.2 < missing < 0.8
    assert rows["half"]["total"] == pytest.approx(90.0 * missing, rel=1e-4)


def test_uncovered_albedo_lowers_psnr_only_over_the_whole_mask(split, case):
    ds, exact, half, _ = case
    rows = {r["name"]: r for r in split([exact, half], ds, "a", layer="albedo")}
    assert rows["exact"]["total"] == np.inf and rows["exact"]["where_predicted"] == np.inf
    assert rows["half"]["where_predicted"] == np.inf and rows["half"]["where_all_predict"] == np.inf
    assert np.isfinite(rows["half"]["total"]) and rows["half"]["total"] < 20
    assert 0.2 < rows["half"]["missing"] < 0.8
