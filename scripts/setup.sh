#!/usr/bin/env bash
# Set-up on a fresh Debian 12 (bookworm): system packages, ONNX Runtime (pinned, fetched into
# the build tree by CMake: deps/onnxruntime.env), a Release build, then the demo render
# (backgrounds drawn by the program, no data set needed) with its contact sheet.
#
#   scripts/setup.sh            install + build + demo
#   scripts/setup.sh --no-demo  install + build only
#   scripts/setup.sh --test     install + build, plus what only the tests need (scripts/test.sh)
#
# PyTorch is not part of this: tools/ has its own opt-in step, scripts/setup-tools.sh.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

run_demo=1
test_packages=0
case "${1:-}" in
  "") ;;
  --no-demo) run_demo=0 ;;
  --test) run_demo=0; test_packages=1 ;;
  -h|--help) sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "setup: unknown option '$1' (scripts/setup.sh [--no-demo | --test]; --help says more)" >&2; exit 2 ;;
esac

packages=(build-essential cmake ninja-build pkg-config ca-certificates dpkg
          libopencv-dev libembree-dev libopenimageio-dev openimageio-tools python3-imath
          libglm-dev libtbb-dev
          nlohmann-json3-dev libcli11-dev libgtest-dev zlib1g-dev libpng-dev libjpeg62-turbo-dev libdeflate-dev
          python3 python3-pip python3-venv)
# qemu-user: the int8 models are tested on an emulated CPU without VNNI
# (tests/remove/test_int8_precision.cpp).
((test_packages)) && packages+=(qemu-user)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}" >&2
  sudo_cmd=()
  [[ $(id -u) -ne 0 ]] && sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release ${RAINDROP_CMAKE_ARGS:-} >&2
cmake --build build --parallel "$(nproc)" >&2

if ((run_demo)); then
  ./build/raindrop-render --demo --out out/demo --variants 2
  # ... and removes drops again with the committed default models (models/DEFAULT), at the
  # 512x256 the networks were trained at (drops far larger in pixels than in training are
  # found only in part: docs/RESULTS.md section 3).
  ./build/raindrop-render --demo --out out/demo-512x256 --size 512x256 --variants 2 -q
  ./build/raindrop-remove out/demo-512x256/rainy out/demo-512x256/removed --mask-dir out/demo-512x256/detected \
    --contact-sheet out/demo/removal_sheet.png -q
  echo "setup: drops removed again: out/demo/removal_sheet.png (rainy | detected mask | removed)" >&2
fi
