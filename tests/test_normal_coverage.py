"""bench/normal_coverage.py splits rh-eval's normal error into direction error and missing coverage."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from rh_common.imageio import read_exr, write_exr
from test_eval_fake import make_dataset, make_predictions

BENCH = Path(__file__).resolve().parents[1] / "bench" / "normal_coverage.py"


def _module():
    spec = importlib.util.spec_from_file_location("normal_coverage", BENCH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_uncovered_pixels_cost_90_degrees_and_are_reported_apart(tmp_path):
    ds = make_dataset(tmp_path / "data")
    exact = make_predictions(ds, tmp_path / "exact", name="exact")
    half = make_predictions(ds, tmp_path / "half", name="half")
    missing = []
    for f in sorted(half.rglob("*_normal.exr")):  # no normal on the left half of the frame: exact elsewhere
        n = read_exr(f)
        person = np.any(n != 0, axis=-1)
        n[:, : n.shape[1] // 2] = 0
        missing.append(1 - np.any(n != 0, axis=-1).sum() / person.sum())
        write_exr(f, n)
    rows = {r["name"]: r for r in _module().split([exact, half], ds, "a")}
    assert rows["exact"]["normal_deg"] == 0.0 and rows["exact"]["missing"] == 0.0
    assert rows["half"]["deg_where_predicted"] == pytest.approx(0.0, abs=1e-3)
    assert rows["half"]["deg_where_all_predict"] == pytest.approx(0.0, abs=1e-3)
    assert rows["half"]["missing"] == pytest.approx(np.mean(missing), abs=1e-6)
    assert 0.2 < rows["half"]["missing"] < 0.8
    assert rows["half"]["normal_deg"] == pytest.approx(90.0 * np.mean(missing), rel=1e-4)
