"""bench/bench_eval.py runs and prints what the issue asks for: pairs per second per metric and the ratio to the
bare backbone passes measured in the same run (the numbers themselves are not asserted: the machine is shared)."""
from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench" / "bench_eval.py"


def test_bench_prints_rates_and_ratios(capsys, monkeypatch):
    spec = importlib.util.spec_from_file_location("bench_eval", BENCH)
    mod = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, mod)  # dataclasses look their module up while the class is made
    spec.loader.exec_module(mod)
    assert mod.main(["--frames", "2", "--size", "64", "--batch-size", "2", "--repeat", "1", "--only", "lpips"]) == 0
    out = capsys.readouterr().out
    assert "2 frame pairs at 64x64" in out and "load average" in out
    row = [l for l in out.splitlines() if l.startswith("lpips (alex)")][0]
    cells = row[len("lpips (alex)"):].split()
    assert len(cells) == 5 and all(re.fullmatch(r"\d+\.\d\dx?", c) for c in cells), row
    assert cells[3].endswith("x") and cells[4].endswith("x")  # cold/bare, warm/bare
