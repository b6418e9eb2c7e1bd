#!/usr/bin/env bash
# Packs what a GPU machine with no package index needs to render this project's frames with Mitsuba's cuda_ad_rgb
# (issue #16 part 4), into .dev/ (ignored through .git/info/exclude), small enough to travel with a checkout:
#   .dev/site.tar.xz    CPython 3.12 x86-64 wheels of this project's pins (constraints.txt), unpacked: Mitsuba with
#                       only its cuda_ad_rgb and scalar_rgb variants (the others are 2/3 of its size), drjit,
#                       colour-science without its tests, OpenEXR. The GPU machine already has numpy, scipy, Pillow
#                       and matplotlib; it lacks anny, warp and newton, so it renders saved scenes instead of posing.
#   .dev/scenes.pkl.xz  the render stage's input of subject 0's test frame 0 of protocol a at 512x512, for the
#                       draft, standard and reference presets (bench/bench_render_stage.py save, ~3 min here).
# Then, on the GPU machine, from the checkout's root: bash tools/device_render_stage.sh (README, "On a GPU").
#   bash tools/device_bundle.sh [PYTHON_VERSION=3.12]
set -euo pipefail
cd "$(dirname "$0")/.."
py=${1:-3.12}
tag=cp${py/./}
grep -qx '/.dev/' .git/info/exclude 2>/dev/null || echo '/.dev/' >> .git/info/exclude
pin() { grep -i "^$1==" constraints.txt | head -1; }
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
for pkg in mitsuba drjit colour-science openexr; do
  python -m pip download -q --disable-pip-version-check --no-deps --only-binary=:all: --python-version "$py" \
    --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
    --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 -d "$work/wheels" "$(pin "$pkg")"
done
mkdir -p "$work/site" .dev
for w in "$work"/wheels/*.whl; do python -m zipfile -e "$w" "$work/site"; done
(
  cd "$work/site"
  # The variants this bundle never sets: each is a 3.5 MB module. Its plugins serve every variant and stay.
  find mitsuba -maxdepth 1 -name "*.cpython-${tag#cp}*-x86_64-linux-gnu.so" \
    | grep -E '/(cuda|llvm|scalar)_[a-z_]+\.' | grep -v -E '/(cuda_ad_rgb|scalar_rgb)\.' | xargs rm -f
  # Headers, CMake files and stubs (the GPU machine compiles nothing against them); colour-science's tests.
  rm -rf mitsuba/include mitsuba/cmake mitsuba/pkgconfig mitsuba/mitsuba_stubs drjit/include share
  find . -name "*.pyi" -delete
  find colour -type d \( -name tests -o -name htmlcov -o -name examples \) -prune -exec rm -rf {} +
  tar cf - ./* | xz -T0 -6 > "$OLDPWD/.dev/site.tar.xz"
)
python bench/bench_render_stage.py save --out .dev --presets draft standard reference --resolution 512
du -ch .dev/* | tail -1
