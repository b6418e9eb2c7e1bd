#!/bin/bash
# Run the published clients' own code on rh-export output, offline, on the CPU (docs/INTEROP.md, "Tried with the
# clients' own code"). No client code is in this repository: CLIENTS holds the user's checkouts of
# taconite/IntrinsicAvatar, jzr99/DNF-Avatar, LuisBolanos17/GaussianShadowCasting and the venv setup_clients.sh made.
#
#   CLIENTS=/path/to/checkouts tools/clients/run_clients.sh EXPORT_A EXPORT_B SMPL_DIR WORK
#
# EXPORT_A / EXPORT_B: rh-export --format relighting-humans --smpl-model SMPL_DIR of protocols a and b
# (published_a / published_b for the 1280x720 camera). Runs IntrinsicAvatar's scripts/preprocess_RANA.py on
# train_p1 and test, DNF-Avatar's on train_p2_p3 (--visualize: its SMPL overlay images), and cells 0-4 of GSC's
# rana_to_h5.ipynb on train_p2_p3, each from a fresh copy of the checkout under WORK. A `wget` that exits 1 stands
# first on PATH and requests.get is served only from EXPORT_B/hdri (py/sitecustomize.py); every attempt is logged
# in WORK/downloads.log. Exit status 0 when all four complete.
set -u
: "${CLIENTS:?set CLIENTS to the folder holding the three client checkouts and venv/}"
A=$(realpath "$1"); B=$(realpath "$2"); SMPL=$(realpath "$3"); W=$4
H=$(cd "$(dirname "$0")" && pwd); PY=${CLIENT_PY:-$CLIENTS/venv/bin/python}
rm -rf "$W"; mkdir -p "$W"; W=$(realpath "$W")
export OPENCV_IO_ENABLE_OPENEXR=1 PATH=$H/bin:$PATH HARNESS_LOG=$W/downloads.log
: > "$W/downloads.log"
status=0
run() {
  local name=$1; shift
  echo "=== $name"
  ( "$@" ) > "$W/$name.log" 2>&1; local rc=$?
  tail -3 "$W/$name.log"; echo "rc=$rc"; [ $rc = 0 ] || status=1
}
for c in IntrinsicAvatar DNF-Avatar; do
  cp -r "$CLIENTS/$c" "$W/$c"; mkdir -p "$W/$c/data/SMPLX/smpl"; cp "$SMPL"/SMPL_*.pkl "$W/$c/data/SMPLX/smpl/"
done
mkdir -p "$W/ia_out/hdri"; cp "$A"/hdri/*.hdr "$W/ia_out/hdri/"   # the export's hdri/, where IntrinsicAvatar looks
cd "$W/IntrinsicAvatar"
run ia_train_p1 env PYTHONPATH="$H/py:." "$PY" scripts/preprocess_RANA.py --data-dir "$A" --split train_p1 --out-dir "$W/ia_out"
run ia_test env PYTHONPATH="$H/py:." "$PY" scripts/preprocess_RANA.py --data-dir "$A" --split test --out-dir "$W/ia_out"
cd "$W/DNF-Avatar"
run dnf_train_p2_p3 env PYTHONPATH="$H/py:." "$PY" scripts/preprocess_RANA.py --data-dir "$B" --split train_p2_p3 --out-dir "$W/dnf_out" --visualize
cp -r "$CLIENTS/GaussianShadowCasting" "$W/GSC"; mkdir -p "$W/GSC/data/HDRis" "$W/GSC/data/RANA"; cd "$W/GSC"
run gsc_cells_0_4 env PYTHONPATH="$H/py:." HARNESS_HDRI_DIR="$B/hdri" "$PY" "$H/run_gsc.py" rana_to_h5.ipynb \
  "$SMPL/SMPL_NEUTRAL.pkl" "$B/train_p2_p3/subject_01/" "$W/GSC/data/RANA/subject_01_train.h5"
echo "=== download attempts (wget calls and requests.get served locally):"; cat "$W/downloads.log"
exit $status
