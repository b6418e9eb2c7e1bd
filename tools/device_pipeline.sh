#!/usr/bin/env bash
# On a GPU machine with Python 3.12, torch and no package index, from this checkout's root (issue #16 part 4):
# the whole pipeline on cuda_ad_rgb, from the packages `tools/device_bundle.sh pipeline` cut into parts. Each call
# carries one part's folder (.dev/pipeline/pN) and runs this script, which keeps the part in /tmp/rh_parts; the call
# that brings the last part unpacks them and runs, writing logs and small datasets under ${OUT:-/tmp/rh_device}:
#   1. anny's mesh cache built there (what setup.sh does);
#   2. the demo protocol at 64x64, draft, on cuda_ad_rgb, twice (same seed: same bits on one GPU?), into
#      demo_cuda.tar: here, `RH_CUDA_DEMO=DIR python -m pytest tests/test_gpu_variant.py` compares it with
#      llvm_ad_rgb layer by layer (the machine has no libLLVM, so the llvm half runs here);
#   3. bench/bench_generate.py, seconds per frame per preset at 512x512 on cuda_ad_rgb, stage by stage;
#   4. rh-generate of one protocol-a subject at 512x512, `standard`, timed end to end under cProfile
#      ($OUT/generate.prof), then rh-verify on it.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/rh_device}
parts=/tmp/rh_parts site=/tmp/rh_site
mkdir -p "$OUT" "$parts"
for d in .dev/pipeline/p*/; do [ -d "$d" ] && cp "$d"part.* "$d"count "$parts"/; done
need=$(cat "$parts/count" 2>/dev/null || echo 0)
have=$(ls "$parts"/part.* 2>/dev/null | wc -l)
if [ "$have" -lt "$need" ] || [ "$need" = 0 ]; then
  echo "device_pipeline: $have of $need parts here; send the next one"; exit 0
fi
if [ ! -d "$site/site/mitsuba" ]; then
  mkdir -p "$site" && cat "$parts"/part.* | xz -dc -T0 | tar xf - -C "$site" || exit 9
fi
# What setup.sh and Debian's blender-data put in place on a development machine.
mkdir -p /usr/share/blender/datafiles/studiolights/world "$HOME/.cache/relighting-humans/drape"
cp "$site"/extra/hdri/* /usr/share/blender/datafiles/studiolights/world/
cp -r "$site"/extra/drape/. "$HOME/.cache/relighting-humans/drape/"
touch /tmp/rh_drape_mark  # drapes written after this were simulated here
export PYTHONPATH="$site/site:$PWD" PATH="$site/site/bin:$PATH" PYTHONUNBUFFERED=1
step() { echo "== $* ($(date -u +%T), load $(cut -d' ' -f1-3 /proc/loadavg))"; }
# Wall seconds of a command (the image may lack /usr/bin/time), printed after its output.
timed() {
  local t0 rc; t0=$(date +%s.%N); "$@"; rc=$?
  echo "[$(python3 -c "print(round($(date +%s.%N) - $t0, 2))") s wall, rc $rc]"
}
{ nvidia-smi; python3 -V; nproc; grep -m1 'model name' /proc/cpuinfo
  python3 -c "import torch, numpy; print('torch', torch.__version__, 'numpy', numpy.__version__)"
  # Does Mitsuba's CUDA backend start here at all? (If not, every step below fails the same way.)
  python3 -c "import mitsuba as mi; mi.set_variant('cuda_ad_rgb'); print('cuda_ad_rgb:', mi.Float([1, 2]) * 2)"
} > "$OUT/machine.txt" 2>&1
cat "$OUT/machine.txt"
{
  step "anny cache"; timed python3 -c "import rh_common.body_model as b; b.warm_cache()" 2>&1 | tail -2
  for run in 1 2; do
    step "demo, cuda_ad_rgb, run $run"
    timed timeout 120 rh-generate --protocol demo --out "/tmp/rh_demo/cuda$run" --frames 2 --resolution 64 \
      --preset draft --variant cuda_ad_rgb --no-progress 2>&1 | grep -v -i warp | tail -3
  done
  # Drapes the carried cache lacked (simulated there, on the CPU): on 5 December the demo's first run compiled and ran
  # newton's solver although this machine's demo hits the cache. The key hashes the pattern's float64 bytes.
  step "drapes simulated there (not in the carried cache)"
  find "$HOME/.cache/relighting-humans/drape" -name '*.npz' -newer /tmp/rh_drape_mark -printf '%f\n' | sort
  step "demo runs 1 and 2, file by file"
  (cd /tmp/rh_demo/cuda1 && find . -type f ! -name '*.log' | sort | xargs sha256sum) > /tmp/rh_demo/s1
  (cd /tmp/rh_demo/cuda2 && find . -type f ! -name '*.log' | sort | xargs sha256sum) > /tmp/rh_demo/s2
  echo "files $(wc -l < /tmp/rh_demo/s1), differing $(diff /tmp/rh_demo/s1 /tmp/rh_demo/s2 | grep -c '^<')"
  diff /tmp/rh_demo/s1 /tmp/rh_demo/s2 | grep '^<' | head -20
  (cd /tmp/rh_demo && tar cf "$OUT/demo_cuda.tar" cuda1)
  step "bench_generate"
  timeout 170 python3 bench/bench_generate.py --presets draft standard reference --repeats 3 --distinct-frames \
    2>&1 | grep -v -i 'warp\|^Module'
  # Under cProfile ($OUT/generate.prof; here `python -m pstats`): on 5 December, without it, the first of these
  # frames came after 57 s where bench_generate had built the same subject in 13 s. The profiler slows the Python
  # parts (posing) a little; the run of 5 December gives the plain figure.
  step "rh-generate under cProfile, protocol a, 1 subject, 8 frames a split, 512x512, standard"
  timed timeout 150 python3 -m cProfile -o "$OUT/generate.prof" "$site/site/bin/rh-generate" --protocol a \
    --subjects 1 --frames 8 --resolution 512 --preset standard --variant cuda_ad_rgb --out /tmp/rh_a 2>&1 \
    | grep -v -i 'warp\|^Module' | tail -4
  step "rh-verify"; timeout 40 rh-verify /tmp/rh_a 2>&1 | tail -4
  (cd /tmp && tar cf "$OUT/a_frame.tar" \
    $(find rh_a -path '*/test/*' \( -name 'frame_000000*' -o -name contact_sheet.png \) | head -20))
  step done
} 2>&1 | tee "$OUT/pipeline.log"
ls -la "$OUT"
