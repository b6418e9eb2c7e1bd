"""bench/compare_results.py: the same predictions under two references, the differences and the methods' order."""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "compare_results.py"


def _module(monkeypatch):
    spec = importlib.util.spec_from_file_location("compare_results", BENCH)
    mod = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, mod)
    spec.loader.exec_module(mod)
    return mod


def _result(folder: Path, stem: str, name: str, kind: str, psnr: float, lpips: float, convention: str = "rana"):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{stem}.json").write_text(json.dumps({
        "kind": kind, "method": {"name": name}, "convention": {"name": convention},
        "overall": {"image_psnr": {"mean": psnr}, "image_lpips": {"mean": lpips}}}))


def test_differences_and_an_order_that_changes(tmp_path, monkeypatch, capsys):
    mod = _module(monkeypatch)
    a, b = tmp_path / "a", tmp_path / "b"
    _result(a, "m1", "One", "method", 22.0, 0.060)
    _result(a, "m2", "Two", "method", 21.5, 0.070)
    _result(a, "oracle", "Bound", "bound", 25.0, 0.030)
    _result(b, "m1", "One", "method", 22.5, 0.075)  # better PSNR, worse LPIPS against the cleaner reference
    _result(b, "m2", "Two", "method", 22.1, 0.068)
    _result(b, "oracle", "Bound", "bound", 26.0, 0.020)
    assert mod.main([str(a), str(b), "--metrics", "psnr,lpips"]) == 0
    out = capsys.readouterr().out
    assert "| One | 22.00 | 22.50 | +0.50 | 0.0600 | 0.0750 | +0.0150 |" in out
    assert "| Bound | 25.00 | 26.00 | +1.00 |" in out
    psnr = next(line for line in out.splitlines() if line.startswith("- image psnr"))
    lpips = next(line for line in out.splitlines() if line.startswith("- image lpips"))
    assert "A: One > Two; B: One > Two (the same order)" in psnr
    assert "A: One > Two; B: Two > One (THE ORDER CHANGES)" in lpips  # lower is better; the bound is left out


def test_refuses_mixed_conventions_and_missing_metrics(tmp_path, monkeypatch):
    mod = _module(monkeypatch)
    a, b = tmp_path / "a", tmp_path / "b"
    _result(a, "m1", "One", "method", 22.0, 0.06)
    _result(b, "m1", "One", "method", 22.5, 0.07, convention="intrinsicavatar")
    with pytest.raises(SystemExit, match="convention 'rana' against 'intrinsicavatar'"):
        mod.main([str(a), str(b), "--metrics", "psnr"])
    _result(b, "m1", "One", "method", 22.5, 0.07)
    with pytest.raises(SystemExit, match="no image_ssim in both"):
        mod.main([str(a), str(b), "--metrics", "ssim"])
    with pytest.raises(SystemExit, match="no such folder"):
        mod.main([str(a), str(tmp_path / "missing")])
