#!/usr/bin/env bash
# The checks that need a GPU, as one prepared run for a device machine (issue #16 part 4): the cuda_ad_rgb test
# (the demo generated on both variants and compared layer by layer) and seconds per frame per preset at 512x512
# on cuda_ad_rgb (bench_generate.py picks cuda_ad_rgb where a GPU works). Writes its logs under ${OUT:-/tmp}.
#   bash setup.sh && bash tools/device_check.sh
# It needs the whole environment (setup.sh: a package index). A GPU machine with none (this workplace's device
# machines) runs tools/device_pipeline.sh there instead, one part of `tools/device_bundle.sh pipeline` a call.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp}
nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1 || true
python -m pytest tests/test_gpu_variant.py -q -rs 2>&1 | tee "$OUT/test_gpu_variant.log"
python bench/bench_generate.py --presets draft standard --repeats 3 2>&1 | tee "$OUT/bench_generate_gpu.log"
