#!/usr/bin/env bash
# On a GPU machine with Python 3.12 and no package index, from this checkout's root with .dev/ beside it
# (tools/device_bundle.sh made it): renders the saved frames on cuda_ad_rgb, timed (bench/bench_render_stage.py
# render), twice: the saved sampler seeds, then the next seeds (the noise yardstick). Writes the logs and one tar of
# rendered frames per preset and seed under ${OUT:-/tmp/rh_device}; bring them back, unpack them in one folder and
# compare with the same scenes rendered here (README, "On a GPU"):
#   python bench/bench_render_stage.py render .dev --layers-out DIR/llvm --variant llvm_ad_rgb --repeats 1
#   python bench/bench_render_stage.py render .dev --layers-out DIR/llvm_s1 --variant llvm_ad_rgb --repeats 1 \
#       --seed-offset 1
#   python bench/bench_render_stage.py compare DIR/cuda DIR/llvm DIR/llvm_s1 DIR/llvm DIR/cuda_s1 DIR/cuda
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/rh_device}
mkdir -p "$OUT"
site=/tmp/rh_site
[ -d "$site/mitsuba" ] || { mkdir -p "$site" && tar xJf .dev/site.tar.xz -C "$site"; } || exit 9
export PYTHONPATH="$site:$PWD" PYTHONUNBUFFERED=1
(nvidia-smi; python3 -V; nproc; grep -m1 'model name' /proc/cpuinfo; cat /proc/loadavg) > "$OUT/machine.txt" 2>&1
python3 bench/bench_render_stage.py render .dev --layers-out /tmp/rh_frames/cuda --variant cuda_ad_rgb --repeats 5 \
  2>&1 | tee "$OUT/render_cuda.log"
python3 bench/bench_render_stage.py render .dev --layers-out /tmp/rh_frames/cuda_s1 --variant cuda_ad_rgb \
  --repeats 3 --seed-offset 1 2>&1 | tee "$OUT/render_cuda_s1.log"
(cd /tmp/rh_frames && tar cf "$OUT/cuda.tar" cuda && tar cf "$OUT/cuda_s1.tar" cuda_s1)
ls -la "$OUT"
