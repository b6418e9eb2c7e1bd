#!/usr/bin/env bash
# The small RANA leaderboard (leaderboards/small/), from scratch: data, pretraining, personalization, predictions,
# rh-eval, rh-leaderboard. Every step resumes when rerun with the same settings.
#
#   bash bench/rana_leaderboard.sh                      # WORK=/tmp/rana_lb, OUT=leaderboards/small
#   WORK=/data/lb STEPS=2000 FREEZE=200 bash bench/rana_leaderboard.sh   # the full cpu-preset schedule
#
# The repository keeps only leaderboard.md and screenshot.png per protocol; index.html stays in $WORK/board_<p>.
# SKIP_DATA=1 reuses existing datasets as they are (rh-generate refuses to resume a folder made by another version
# of the generator). Benchmark: 2 subjects x protocols a and b, 20 train + 20 test frames at 128 px, draft render preset.
# Methods (rows): RANA (cpu preset, STEPS personalization steps, no pretraining), RANA without the albedo
# regulariser (Table 1 ablation), RANA with pretraining (PRE_SUBJECTS pretraining characters x PRE_FRAMES AOV-only
# frames; TextureNet TEX_STEPS and G_N/G_A PRE_STEPS steps), SMPL+D (coarse stage of the RANA runs), and the Lambertian-SH
# oracle bound (listed apart, never ranked). Pretraining and the two protocols run in parallel, one torch
# thread each.
set -euo pipefail
cd "$(dirname "$0")/.."

WORK=${WORK:-/tmp/rana_lb}
OUT=${OUT:-leaderboards/small}
STEPS=${STEPS:-50}
FREEZE=${FREEZE:-10}
PRETRAIN=${PRETRAIN:-1}   # 0 = leave out the "RANA + pretraining" row (and the pretraining)
THREADS=${THREADS:-1}
PRE_SUBJECTS=${PRE_SUBJECTS:-6}    # pretraining characters (the paper: 400)
PRE_FRAMES=${PRE_FRAMES:-20}       # AOV-only frames per pretraining character (the paper: 150)
PRE_STEPS=${PRE_STEPS:-400}        # G_N/G_A pretraining steps
TEX_STEPS=${TEX_STEPS:-300}        # TextureNet steps
DATA=${DATA:-$WORK/data}
PRE_DATA=${PRE_DATA:-$WORK/pretrain_data}
PRE=${PRE:-$WORK/pretrained}
mkdir -p "$WORK" "$OUT"
SECONDS=0
stamp() { echo "== $(date +%H:%M:%S) [${SECONDS}s] $*"; }

stamp "data"
if [ "${SKIP_DATA:-0}" = 1 ]; then
  echo "SKIP_DATA=1: using the datasets already in $DATA and $PRE_DATA as they are"
else
  for p in a b; do
    rh-generate --protocol $p --out "$DATA" --subjects 2 --frames 20 --resolution 128 --preset draft --no-progress
  done
  rh-generate --protocol scenes/rana_pretrain.json --out "$PRE_DATA" --subjects "$PRE_SUBJECTS" --frames "$PRE_FRAMES" --resolution 128 \
    --preset draft --no-progress
fi

# Pretraining runs beside the protocols' first two variants; the pretrained variant waits for it.
pretraining() {
  stamp "pretraining"
  if rana-pretrain --dataset "$PRE_DATA" --out "$PRE" --preset cpu --threads "$THREADS" --geometry.steps 60 \
      --texture.steps "$TEX_STEPS" --pretrain.steps "$PRE_STEPS" --pretrain.checkpoint_every 100 --no-progress; then
    touch "$WORK/pretraining.ok"
  else
    touch "$WORK/pretraining.failed"
  fi
  stamp "pretraining finished"
}
wait_pretraining() {
  while [ ! -e "$WORK/pretraining.ok" ] && [ ! -e "$WORK/pretraining.failed" ]; do sleep 10; done
  [ -e "$WORK/pretraining.ok" ]
}
rm -f "$WORK/pretraining.ok" "$WORK/pretraining.failed"

COMMON=(--preset cpu --threads "$THREADS" --personalize.steps "$STEPS" --personalize.freeze_albedo_steps "$FREEZE"
        --personalize.checkpoint_every 50 --no-progress)

protocol() {
  local p=$1 R="$WORK/runs_$1" P="$WORK/preds_$1" E="$WORK/results_$1"
  mkdir -p "$E"
  stamp "protocol $p: personalization"
  rana train --dataset "$DATA" --protocol $p --runs "$R/rana" "${COMMON[@]}"
  # The ablation's coarse stage has the same settings as the full run's: share it instead of recomputing it.
  for s in $(ls -d "$R/rana"/subject_* | xargs -n1 basename); do
    mkdir -p "$R/no_albedo_reg/$s"
    [ -e "$R/no_albedo_reg/$s/coarse.pt" ] || cp "$R/rana/$s/coarse.pt" "$R/no_albedo_reg/$s/coarse.pt"
  done
  rana train --dataset "$DATA" --protocol $p --runs "$R/no_albedo_reg" "${COMMON[@]}" --loss.lambda_albedo_reg 0
  local methods="rana no_albedo_reg smpld oracle"
  if [ "$PRETRAIN" = 1 ] && wait_pretraining; then
    rana train --dataset "$DATA" --protocol $p --runs "$R/pretrained" "${COMMON[@]}" --pretrained "$PRE/pretrained.pt"
    rana predict --dataset "$DATA" --protocol $p --runs "$R/pretrained" --out "$P/pretrained" --no-progress \
      --name "RANA + pretraining ($PRE_SUBJECTS chars)"
    methods="$methods pretrained"
  fi
  stamp "protocol $p: predictions"
  rana predict --dataset "$DATA" --protocol $p --runs "$R/rana" --out "$P/rana" --no-progress \
    --name "RANA (cpu, $STEPS steps, no pretraining)"
  rana predict --dataset "$DATA" --protocol $p --runs "$R/no_albedo_reg" --out "$P/no_albedo_reg" --no-progress \
    --name "RANA w/o albedo regulariser"
  rana smpld --dataset "$DATA" --protocol $p --runs "$R/rana" --out "$P/smpld" --no-progress
  rana-oracle --dataset "$DATA" --protocol $p --out "$P/oracle"
  stamp "protocol $p: evaluation"
  for m in $methods; do
    rh-eval "$P/$m" --dataset "$DATA" --protocol $p --out "$E/$m.json"
  done
  rh-leaderboard "$E"/*.json --out "$WORK/board_$p"
  mkdir -p "$OUT/protocol_$p"
  cp "$WORK/board_$p/leaderboard.md" "$OUT/protocol_$p/leaderboard.md"
  stamp "protocol $p: done"
}

pp=
if [ "$PRETRAIN" = 1 ]; then
  pretraining > "$WORK/pretraining.log" 2>&1 &
  pp=$!
fi
protocol a > "$WORK/protocol_a.log" 2>&1 &
pa=$!
protocol b > "$WORK/protocol_b.log" 2>&1 &
pb=$!
rc=0
[ -z "$pp" ] || wait $pp || rc=1
wait $pa || rc=1
wait $pb || rc=1
tail -n 3 "$WORK/protocol_a.log" "$WORK/protocol_b.log"
# A screenshot of each board's index.html (when chromium is installed).
if command -v chromium > /dev/null; then
  for p in a b; do
    [ -e "$WORK/board_$p/index.html" ] || continue
    chromium --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking \
      --disable-component-update --disable-sync --user-data-dir="$WORK/chromium" --window-size=1200,900 \
      --screenshot="$OUT/protocol_$p/screenshot.png" "file://$(cd "$WORK/board_$p" && pwd)/index.html" \
      > /dev/null 2>&1 || echo "screenshot of protocol $p failed"
  done
fi
stamp "done (exit $rc); leaderboard.md + screenshot.png in $OUT/protocol_{a,b}; full HTML in $WORK/board_{a,b}"
exit $rc
