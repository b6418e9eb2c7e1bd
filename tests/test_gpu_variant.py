"""The GPU path (issue #16 part 4): `cuda_ad_rgb` runs the same pipeline with no code change.

Where a CUDA device works, the demo protocol is generated twice at 64x64, once per variant, and the two datasets
are compared layer by layer with `rh-verify --against`'s comparison. The two variants draw the same samples
(Mitsuba's samplers are seeded identically on both backends); they differ only in floating-point evaluation
order, fused multiply-adds and the GPU's intersection code, so the frames agree closely but not bit for bit.
Where no CUDA device works (this project's CI, the 2-core development machines), the test is skipped and says
so. On a device machine: `bash tools/device_check.sh` runs this test and the per-preset timing bench. A GPU machine
that cannot install the environment runs `tools/device_pipeline.sh`, which makes the cuda_ad_rgb half there (it has
no libLLVM for the other); then `RH_CUDA_DEMO=DIR python -m pytest tests/test_gpu_variant.py` here compares that
dataset with the llvm_ad_rgb half made here (docs/TRADEOFFS.md, "The GPU path").
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rh_common.layout.compare import compare_datasets

_PROBE = ("from rh_dataset.variant import select_variant; import sys; "
          "sys.exit(0 if select_variant(None) == 'cuda_ad_rgb' else 3)")


def _cuda_works() -> bool:
    return subprocess.run([sys.executable, "-c", _PROBE], capture_output=True).returncode == 0


# A cuda_ad_rgb demo dataset made on another machine by `_generate` (tools/device_pipeline.sh), if any.
_CUDA_DEMO = os.environ.get("RH_CUDA_DEMO")

pytestmark = pytest.mark.skipif(not _CUDA_DEMO and not _cuda_works(),
                                reason="no CUDA device: Mitsuba's cuda_ad_rgb cannot initialise on this machine (the "
                                "GPU path is checked on a device machine)")

# Lowest per-frame PSNR (peak = the frame's max) accepted between the two backends' layers: far above the
# images' own noise floor at the draft preset, far below bit-identity.
_MIN_PSNR_DB = {"image": 30.0, "mask": 30.0, "albedo": 30.0, "normal": 30.0, "depth": 30.0}


def _generate(out, variant):
    subprocess.run(["rh-generate", "--protocol", "demo", "--out", str(out), "--frames", "2", "--resolution", "64",
                    "--preset", "draft", "--variant", variant, "--no-progress"], check=True)


def test_cuda_and_llvm_give_the_same_frames_within_noise(tmp_path):
    cuda = tmp_path / "cuda"
    if _CUDA_DEMO:
        cuda = Path(_CUDA_DEMO)
        assert (cuda / "manifest.json").is_file(), f"RH_CUDA_DEMO={cuda}: not a dataset folder"
        frame = next(cuda.glob("subject_*/protocol_*/test/frame_000000.json"))
        assert json.loads(frame.read_text())["render"]["variant"] == "cuda_ad_rgb", f"{frame}: not made on the GPU"
    else:
        _generate(cuda, "cuda_ad_rgb")
    _generate(tmp_path / "llvm", "llvm_ad_rgb")
    cmp = compare_datasets(cuda, tmp_path / "llvm")
    assert not cmp.mismatches, cmp.mismatches  # same frames, cameras, poses and lights
    checked = 0
    for key, diff in cmp.layers.items():
        layer = key.split("/")[-1].split(".")[0]
        if diff.is_8bit or layer not in _MIN_PSNR_DB:
            continue
        checked += 1
        assert diff.min_psnr_db >= _MIN_PSNR_DB[layer] or math.isinf(diff.min_psnr_db), (key, diff.to_json())
    assert checked >= 5
