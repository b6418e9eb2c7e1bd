#!/usr/bin/env bash
# Packs what a GPU machine with no package index needs (issue #16 part 4), into .dev/ (ignored through
# .git/info/exclude), in pieces small enough to travel with a checkout (64 MiB a call on this workplace's machines).
#   bash tools/device_bundle.sh [render] [PYTHON_VERSION=3.12]
#     .dev/site.tar.xz    CPython 3.12 x86-64 wheels of this project's pins (constraints.txt), unpacked: Mitsuba with
#                         only its cuda_ad_rgb and scalar_rgb variants (the others are 2/3 of its size), drjit,
#                         colour-science without its tests, OpenEXR.
#     .dev/scenes.pkl.xz  the render stage's input of subject 0's test frame 0 of protocol a at 512x512, for the
#                         draft, standard and reference presets (bench/bench_render_stage.py save, ~3 min here).
#     Then, on the GPU machine, from the checkout's root: bash tools/device_render_stage.sh (README, "On a GPU").
#   bash tools/device_bundle.sh pipeline [PYTHON_VERSION=3.12]
#     .dev/pipeline/pN/   the whole pipeline's missing packages (the above, and anny, warp, newton, trimesh, rtree,
#                         libigl, roma; the GPU machine has torch, numpy, scipy, Pillow, matplotlib, tqdm, pytest), console
#                         scripts for the checkout's entry points, the 8 bundled HDRIs (Debian's blender-data) and
#                         this machine's drape cache, as one xz stream cut into parts of 60 MB, one folder each.
#     Then, on the GPU machine, one call per part, each carrying its folder:
#       bash tools/device_pipeline.sh     (it keeps the parts in /tmp; with the last one it unpacks and runs)
#     Calls must follow within the machine's warm time, or the parts already sent are lost with it.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=render
case "${1:-}" in render|pipeline) mode=$1; shift;; esac
py=${1:-3.12}
tag=cp${py/./}
grep -qx '/.dev/' .git/info/exclude 2>/dev/null || echo '/.dev/' >> .git/info/exclude
pin() { grep -i "^$1==" constraints.txt | head -1; }
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
pkgs=(mitsuba drjit colour-science openexr)
[ "$mode" = pipeline ] && pkgs+=(anny warp-lang newton trimesh rtree libigl roma)
for pkg in "${pkgs[@]}"; do
  python -m pip download -q --disable-pip-version-check --no-deps --only-binary=:all: --python-version "$py" \
    --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
    --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 -d "$work/wheels" "$(pin "$pkg")"
done
mkdir -p "$work/site" .dev
for w in "$work"/wheels/*.whl; do python -m zipfile -e "$w" "$work/site"; done
(
  cd "$work/site"
  # The variants this bundle never sets: each is a 3.5 MB module. Its plugins serve every variant and stay.
  # (llvm_ad_rgb would need libLLVM, which the GPU machine lacks.)
  find mitsuba -maxdepth 1 -name "*.cpython-${tag#cp}*-x86_64-linux-gnu.so" \
    | grep -E '/(cuda|llvm|scalar)_[a-z_]+\.' | grep -v -E '/(cuda_ad_rgb|scalar_rgb)\.' | xargs rm -f
  # Headers, CMake files and stubs (the GPU machine compiles nothing against them); tests and examples.
  # warp/native stays: Warp compiles its CPU kernels (anny's skinning) against those headers.
  rm -rf mitsuba/include mitsuba/cmake mitsuba/pkgconfig mitsuba/mitsuba_stubs drjit/include share
  find . -name "*.pyi" -delete
  find colour warp newton anny -maxdepth 3 -type d \( -name tests -o -name htmlcov -o -name examples \) \
    -prune -exec rm -rf {} + 2>/dev/null || true
)
if [ "$mode" = render ]; then
  (cd "$work/site" && tar cf - ./* | xz -T0 -6 > "$OLDPWD/.dev/site.tar.xz")
  python bench/bench_render_stage.py save --out .dev --presets draft standard reference --resolution 512
  du -ch .dev/site.tar.xz .dev/scenes.pkl.xz | tail -1
  exit 0
fi
# What `pip install` would have written into bin/: one script per [project.scripts] entry of pyproject.toml.
mkdir -p "$work/site/bin"
sed -n '/^\[project.scripts\]/,/^$/p' pyproject.toml | grep '=' | tr -d '" ' | while IFS='=' read -r name target; do
  printf '#!/usr/bin/env python3\nimport sys\nfrom %s import %s\nsys.exit(%s())\n' \
    "${target%%:*}" "${target##*:}" "${target##*:}" > "$work/site/bin/$name"
  chmod +x "$work/site/bin/$name"
done
mkdir -p "$work/extra/hdri" "$work/extra/drape"
cp /usr/share/blender/datafiles/studiolights/world/* "$work/extra/hdri/"
drape=${RH_DRAPE_CACHE:-$HOME/.cache/relighting-humans/drape}
[ -d "$drape" ] && cp -r "$drape"/. "$work/extra/drape/"
rm -rf .dev/pipeline && mkdir -p .dev/pipeline
(cd "$work" && tar cf - site extra | xz -T0 -6 | split -b 60000000 -d -a 1 - "$work/part.")
n=$(ls "$work"/part.* | wc -l)
i=1
for f in "$work"/part.*; do
  mkdir -p ".dev/pipeline/p$i"; mv "$f" ".dev/pipeline/p$i/"; echo "$n" > ".dev/pipeline/p$i/count"; i=$((i + 1))
done
du -sh .dev/pipeline/p*
