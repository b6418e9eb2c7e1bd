#!/usr/bin/env bash
# The small RANA leaderboard (leaderboards/small/), from scratch: data, pretraining, personalization, predictions,
# rh-eval, rh-leaderboard. Every step resumes when rerun with the same settings.
#
#   bash bench/rana_leaderboard.sh                          # WORK=/tmp/rana_lb, OUT=leaderboards/small, a quick run
#   WORK=/data/lb STEPS=2000 FREEZE=200 bash bench/rana_leaderboard.sh   # the full cpu-preset schedule
#
# The repository keeps leaderboard.md, screenshot.png (the tables) and pictures.png (the test split's image
# strips) per protocol; index.html and its pictures stay in $WORK/board_<p>.
# SKIP_DATA=1 reuses existing datasets as they are (rh-generate refuses to resume a folder made by another version
# of the generator). Benchmark: 2 subjects x protocols a and b, 20 train + 20 test frames at 128 px, PRESET render preset
# (default standard, the full benchmark's: at draft's 16 spp a fifth of the oracle bound's squared error was the
# ground truth's own noise, leaderboards/small/README.md; the three datasets took 745 s at standard against 256 s at
# draft, each beside the fresh-clone CI at load 2.4-4.6, of a board of ~45-55 min).
# Rows, as in the paper's Table 1 (the full method and its ablations, same schedule):
#   RANA                         cpu preset, STEPS personalization steps, pretrained (PRE_SUBJECTS characters x
#                                PRE_FRAMES AOV-only frames; TextureNet TEX_STEPS and G_N/G_A PRE_STEPS steps)
#   RANA w/o pretraining         the same from scratch (residual heads on the exposure-SH coarse albedo)
#   RANA w/o albedo regulariser  pretrained, lambda_albedo_reg = 0
#   SMPL+D                       the coarse stage, once with TextureNet's albedo (the paper's) and once with the
#                                exposure-SH albedo of the runs without pretraining
#   oracle bound                 listed apart, never ranked
# PRETRAIN=0 leaves out pretraining, its data and every row that needs it. The no-pretraining runs go beside the pretraining
# (one torch thread each); the pretrained runs of both protocols follow it in parallel.
# PHASES (default "all") runs a part only, for a board made in pieces: "scratch" (the rows without pretraining),
# "pretrain" (pretraining, then the pretrained rows), "board" (rh-eval, rh-leaderboard, screenshots), or a list.
# OLAT=1 (default) generates the olat_a / olat_b scenes instead of a / b: their train and test splits are a's and
# b's byte for byte, plus an `olat` split (test poses under single lights, frame i = pose i // 16, light i % 16),
# which every row also predicts and is scored on (tables of their own on each board). OLAT=0: a and b only.
set -euo pipefail
cd "$(dirname "$0")/.."

WORK=${WORK:-/tmp/rana_lb}
OUT=${OUT:-leaderboards/small}
STEPS=${STEPS:-50}
FREEZE=${FREEZE:-10}
OLAT=${OLAT:-1}
PRETRAIN=${PRETRAIN:-1}   # 0 = leave out the "RANA + pretraining" row (and the pretraining)
THREADS=${THREADS:-1}
PRESET=${PRESET:-standard}         # rh-generate --preset of every dataset the board makes
PRE_SUBJECTS=${PRE_SUBJECTS:-6}    # pretraining characters (the paper: 400)
PRE_FRAMES=${PRE_FRAMES:-20}       # AOV-only frames per pretraining character (the paper: 150)
PRE_STEPS=${PRE_STEPS:-400}        # G_N/G_A pretraining steps
ALBEDO_REG_ABLATION=${ALBEDO_REG_ABLATION:-a b}   # protocols that get the "w/o albedo regulariser" row
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
    scene=$p; [ "$OLAT" = 1 ] && scene=olat_$p
    rh-generate --protocol $scene --out "$DATA" --subjects 2 --frames 20 --resolution 128 --preset "$PRESET" --no-progress
  done
  # The pretraining frames only feed the pretraining: PRETRAIN=0 makes none (they were 1485 s of the last board).
  if [ "$PRETRAIN" = 1 ]; then
    rh-generate --protocol rana_pretrain --out "$PRE_DATA" --subjects "$PRE_SUBJECTS" --frames "$PRE_FRAMES" \
      --resolution 128 --preset "$PRESET" --no-progress
  fi
fi

pretraining() {
  stamp "pretraining"
  if rana-pretrain --dataset "$PRE_DATA" --out "$PRE" --preset cpu --threads "$THREADS" --geometry.steps 60 \
      --texture.steps "$TEX_STEPS" --pretrain.steps "$PRE_STEPS" --pretrain.max_subjects "$PRE_SUBJECTS" \
      --pretrain.checkpoint_every 100 --no-progress; then
    touch "$WORK/pretraining.ok"
  else
    touch "$WORK/pretraining.failed"
  fi
  stamp "pretraining finished"
}
rm -f "$WORK/pretraining.ok" "$WORK/pretraining.failed"

COMMON=(--preset cpu --threads "$THREADS" --personalize.steps "$STEPS" --personalize.freeze_albedo_steps "$FREEZE"
        --personalize.checkpoint_every 50 --no-progress)

# Personalization of one variant on one protocol: runs in $WORK/runs_<p>/<variant>, predictions in $WORK/preds_<p>.
variant() {
  local p=$1 v=$2 name=$3; shift 3
  stamp "protocol $p: $v"
  rana train --dataset "$DATA" --protocol $p --runs "$WORK/runs_$p/$v" "${COMMON[@]}" "$@"
  rana predict --dataset "$DATA" --protocol $p --runs "$WORK/runs_$p/$v" --out "$WORK/preds_$p/$v" --no-progress \
    --name "$name"
  if [ "$OLAT" = 1 ]; then
    rana predict --dataset "$DATA" --protocol $p --runs "$WORK/runs_$p/$v" --out "$WORK/preds_${p}_olat/$v" \
      --no-progress --name "$name" --split olat
  fi
}
# SMPL+D from a run's coarse stage (test split, and olat when OLAT=1).
smpld() {
  local p=$1 run=$2 out=$3 name=$4
  rana smpld --dataset "$DATA" --protocol $p --runs "$run" --out "$WORK/preds_$p/$out" --no-progress --name "$name"
  if [ "$OLAT" = 1 ]; then
    rana smpld --dataset "$DATA" --protocol $p --runs "$run" --out "$WORK/preds_${p}_olat/$out" --no-progress \
      --name "$name" --split olat
  fi
}
# The ablation's coarse stage has the same settings as its source run's: share it instead of recomputing it.
share_coarse() {
  local from=$1 to=$2
  for s in $(ls -d "$from"/subject_* | xargs -n1 basename); do
    mkdir -p "$to/$s"
    [ -e "$to/$s/coarse.pt" ] || cp "$from/$s/coarse.pt" "$to/$s/coarse.pt"
  done
}
scratch() {  # everything that needs no pretraining, protocols one after the other
  for p in a b; do
    variant $p no_pretraining "RANA w/o pretraining (cpu, $STEPS steps)"
    smpld $p "$WORK/runs_$p/no_pretraining" smpld_exposure_sh "SMPL+D (exposure-SH albedo)"
    rana-oracle --dataset "$DATA" --protocol $p --out "$WORK/preds_$p/oracle"
    if [ "$OLAT" = 1 ]; then
      rana-oracle --dataset "$DATA" --protocol $p --out "$WORK/preds_${p}_olat/oracle" --split olat
    fi
  done
}
pretrained() {  # the full method and its albedo-regulariser ablation on one protocol
  local p=$1
  variant $p rana "RANA (cpu, $STEPS steps, $PRE_SUBJECTS pretraining chars)" --pretrained "$PRE/pretrained.pt"
  if [[ " $ALBEDO_REG_ABLATION " == *" $p "* ]]; then
    share_coarse "$WORK/runs_$p/rana" "$WORK/runs_$p/no_albedo_reg"
    variant $p no_albedo_reg "RANA w/o albedo regulariser" --pretrained "$PRE/pretrained.pt" --loss.lambda_albedo_reg 0
  fi
  smpld $p "$WORK/runs_$p/rana" smpld "SMPL+D (TextureNet albedo)"
}
board() {
  local p=$1 E="$WORK/results_$p"
  mkdir -p "$E" "$OUT/protocol_$p"
  stamp "protocol $p: evaluation"
  for m in $(ls "$WORK/preds_$p"); do
    rh-eval "$WORK/preds_$p/$m" --dataset "$DATA" --protocol $p --out "$E/$m.json" --no-progress
  done
  if [ -d "$WORK/preds_${p}_olat" ]; then
    stamp "protocol $p: evaluation of the olat split"
    for m in $(ls "$WORK/preds_${p}_olat"); do
      rh-eval "$WORK/preds_${p}_olat/$m" --dataset "$DATA" --protocol $p --split olat --out "$E/${m}_olat.json" \
        --no-progress
    done
  fi
  rh-leaderboard "$E"/*.json --out "$WORK/board_$p"
  cp "$WORK/board_$p/leaderboard.md" "$OUT/protocol_$p/leaderboard.md"
}

PHASES=${PHASES:-all}
[ "$PHASES" = all ] && PHASES="scratch pretrain board"
has() { [[ " $PHASES " == *" $1 "* ]]; }
for ph in $PHASES; do
  case $ph in scratch|pretrain|board) ;; *) echo "PHASES: unknown phase '$ph' (scratch, pretrain, board, all)"; exit 2;; esac
done

rc=0
if ! has pretrain; then
  if has scratch; then scratch > "$WORK/scratch.log" 2>&1 || rc=1; fi
elif [ "$PRETRAIN" = 1 ]; then
  pretraining > "$WORK/pretraining.log" 2>&1 &
  pp=$!
  if has scratch; then scratch > "$WORK/scratch.log" 2>&1 || rc=1; fi
  wait $pp || rc=1
  if [ -e "$WORK/pretraining.ok" ]; then
    pretrained a > "$WORK/pretrained_a.log" 2>&1 &
    pa=$!
    pretrained b > "$WORK/pretrained_b.log" 2>&1 || rc=1
    wait $pa || rc=1
  else
    echo "pretraining failed (see $WORK/pretraining.log): no pretrained rows"; rc=1
  fi
elif has scratch; then
  scratch > "$WORK/scratch.log" 2>&1 || rc=1
fi
if has board; then
  for p in a b; do board $p >> "$WORK/board.log" 2>&1 || rc=1; done
fi
# A screenshot of each board's index.html (when chromium is installed).
if has board && command -v chromium > /dev/null; then
  for p in a b; do
    [ -e "$WORK/board_$p/index.html" ] || continue
    shot() {  # shot PAGE PNG WIDTH,HEIGHT
      chromium --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking \
        --disable-component-update --disable-sync --user-data-dir="$WORK/chromium" --window-size="$3" \
        --virtual-time-budget=3000 --screenshot="$2" "file://$(cd "$WORK/board_$p" && pwd)/$1" > /dev/null 2>&1
    }
    shot index.html "$OUT/protocol_$p/screenshot.png" 1400,1250 || echo "screenshot of protocol $p failed"
    # The test split's image strips alone (bench/page_section.py hides the rest of a copy of the page).
    python bench/page_section.py "$WORK/board_$p/index.html" "$WORK/board_$p/_pictures.html" &&
      shot _pictures.html "$OUT/protocol_$p/pictures.png" 1000,1150 || echo "pictures of protocol $p failed"
    rm -f "$WORK/board_$p/_pictures.html"
  done
fi
stamp "done (exit $rc); leaderboard.md + screenshot.png in $OUT/protocol_{a,b}; full HTML in $WORK/board_{a,b}"
exit $rc
