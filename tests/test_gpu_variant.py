"""The GPU path (issue #16 part 4): `cuda_ad_rgb` runs the same pipeline with no code change.

Where a CUDA device works, the demo protocol is generated twice at 64x64, once per variant, and the two datasets
are compared layer by layer with `rh-verify --against`'s comparison. The two variants draw the same samples
(Mitsuba's samplers are seeded identically on both backends); they differ only in floating-point evaluation
order, fused multiply-adds and the GPU's intersection code, so the frames agree closely but not bit for bit.
Where no CUDA device works (this project's CI, the 2-core development machines), the test is skipped and says
so. On a device machine: `bash tools/device_check.sh` runs this test and the per-preset timing bench; where that
machine cannot install the environment, bench/bench_render_stage.py compares the two variants on saved frames
(docs/TRADEOFFS.md, "The GPU path").
"""
from __future__ import annotations

import math
import subprocess
import sys

import pytest

from rh_common.layout.compare import compare_datasets

_PROBE = ("from rh_dataset.variant import select_variant; import sys; "
          "sys.exit(0 if select_variant(None) == 'cuda_ad_rgb' else 3)")


def _cuda_works() -> bool:
    return subprocess.run([sys.executable, "-c", _PROBE], capture_output=True).returncode == 0


pytestmark = pytest.mark.skipif(not _cuda_works(), reason="no CUDA device: Mitsuba's cuda_ad_rgb cannot "
                                "initialise on this machine (the GPU path is checked on a device machine)")

# Lowest per-frame PSNR (peak = the frame's max) accepted between the two backends' layers: far above the
# images' own noise floor at the draft preset, far below bit-identity.
_MIN_PSNR_DB = {"image": 30.0, "mask": 30.0, "albedo": 30.0, "normal": 30.0, "depth": 30.0}


def _generate(out, variant):
    subprocess.run(["rh-generate", "--protocol", "demo", "--out", str(out), "--frames", "2", "--resolution", "64",
                    "--preset", "draft", "--variant", variant, "--no-progress"], check=True)


def test_cuda_and_llvm_give_the_same_frames_within_noise(tmp_path):
    _generate(tmp_path / "cuda", "cuda_ad_rgb")
    _generate(tmp_path / "llvm", "llvm_ad_rgb")
    cmp = compare_datasets(tmp_path / "cuda", tmp_path / "llvm")
    assert not cmp.mismatches, cmp.mismatches  # same frames, cameras, poses and lights
    checked = 0
    for key, diff in cmp.layers.items():
        layer = key.split("/")[-1].split(".")[0]
        if diff.is_8bit or layer not in _MIN_PSNR_DB:
            continue
        checked += 1
        assert diff.min_psnr_db >= _MIN_PSNR_DB[layer] or math.isinf(diff.min_psnr_db), (key, diff.to_json())
    assert checked >= 5
