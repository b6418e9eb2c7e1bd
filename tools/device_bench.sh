#!/usr/bin/env bash
# The second call of a GPU session (issue #16 part 4): on the machine tools/device_pipeline.sh has just unpacked
# (still warm: /tmp/rh_site holds the packages), bench_generate.py with more frames, the rows timed in turn, and two
# rows beside the presets: `standard` with every pixel at its spp (no environment split) and the settings before
# bench_sampler (independent 128 spp, AOV 16). Writes $OUT/bench_interleaved.log.
set -uo pipefail
cd "$(dirname "$0")/.."
[ -d /tmp/rh_site/site/mitsuba ] || { echo "device_bench: run tools/device_pipeline.sh on this machine first"; exit 2; }
export PYTHONPATH=/tmp/rh_site/site:$PWD PATH=/tmp/rh_site/site/bin:$PATH PYTHONUNBUFFERED=1
timeout 280 python3 bench/bench_generate.py --presets draft standard reference --repeats 5 --distinct-frames \
  --interleave --also standard:multijitter:156 standard:independent:128::16 2>&1 \
  | grep -v -i 'warp\|^Module\|^   ' | tee "${OUT:-/tmp}/bench_interleaved.log"
