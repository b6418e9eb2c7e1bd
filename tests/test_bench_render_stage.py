"""bench/bench_render_stage.py, the way a GPU session uses it (docs/TRADEOFFS.md, "The GPU path"): scenes saved
here render elsewhere to dataset-shaped frames that rh-verify's comparison reads. Here both ends run on llvm_ad_rgb
at 32x32, so the rendered frames must be the saved frames' bits, and another seed must differ."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from rh_common.layout.compare import compare_datasets

BENCH = Path(__file__).resolve().parents[1] / "bench" / "bench_render_stage.py"


def _run(*args: str) -> str:
    return subprocess.run([sys.executable, str(BENCH), *args], check=True, capture_output=True, text=True).stdout


def test_saved_scenes_render_again_to_the_same_frames_and_another_seed_differs(tmp_path):
    _run("save", "--out", str(tmp_path), "--presets", "draft", "--resolution", "32")
    assert (tmp_path / "scenes.pkl.xz").is_file()
    out = {}
    for name, offset in (("a", "0"), ("b", "0"), ("s1", "1")):
        table = _run("render", str(tmp_path), "--layers-out", str(tmp_path / name), "--variant", "llvm_ad_rgb",
                     "--repeats", "1", "--seed-offset", offset)
        assert "| draft | 0 | " in table and "Mitsuba variant llvm_ad_rgb" in table
        out[name] = tmp_path / name
    same = compare_datasets(out["a"], out["b"])
    assert not same.mismatches and same.layers and all(d.frames_differing == 0 for d in same.layers.values())
    other = compare_datasets(out["a"], out["s1"])
    assert not other.mismatches and other.layers["protocol_a/draft/image.exr"].frames_differing == 1
    assert "| protocol_a/draft/image.exr | identical |" in _run("compare", str(out["a"]), str(out["b"]))
