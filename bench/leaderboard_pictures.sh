#!/usr/bin/env bash
# The README's leaderboard screenshot (docs/leaderboard_pictures.png): rh-demo's chain (tiny dataset, the
# Lambertian-SH oracle and SMPL+D, rh-eval, rh-leaderboard), then a headless-Chromium screenshot of the page. Prints
# each result's picture bytes (rh-eval's own count) and the board folder's size, with the machine's load.
#
#   bash bench/leaderboard_pictures.sh                 # WORK=/tmp/rh_pictures, writes docs/leaderboard_pictures.png
#
# Run from the repository root (the code used is this checkout's: PYTHONPATH=$PWD).
set -euo pipefail
WORK=${WORK:-/tmp/rh_pictures}
SHOT=${SHOT:-docs/leaderboard_pictures.png}
export PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH}
echo "load at start: $(cat /proc/loadavg)"
[ -f "$WORK/results/smpld.json" ] || python -c "import sys; from rh_demo import main; sys.exit(main(['--out', '$WORK']))"
for m in oracle smpld; do  # again with this checkout's rh-eval, so the pictures are its own
  python -m rh_eval.cli "$WORK/predictions/$m" --dataset "$WORK/data" --protocol a --out "$WORK/results/$m.json" \
    --no-progress | tail -1
done
python -m rh_eval.leaderboard "$WORK/results/smpld.json" "$WORK/results/oracle.json" --out "$WORK/leaderboard"
echo "board folder: $(du -sb "$WORK/leaderboard" | cut -f1) bytes (pictures/: $(du -sb "$WORK/leaderboard/pictures" | cut -f1))"
chromium --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking \
  --disable-component-update --disable-sync --user-data-dir="$WORK/chrome" --window-size=1400,1500 \
  --virtual-time-budget=2000 --screenshot="$SHOT" "file://$(cd "$WORK/leaderboard" && pwd)/index.html" > /dev/null 2>&1
echo "wrote $SHOT; load at end: $(cat /proc/loadavg)"
