#!/usr/bin/env bash
# The test command (README; .ci/run calls exactly this): set-up and build as
# scripts/setup.sh does (without the demo, with the test-only packages), the Python tools
# environment, then every test under ctest.
#
# The tools environment includes PyTorch (about 2.8 GB, a minute or two from PyPI) so that the
# export-parity and training tests run. RAINDROP_TEST_NO_TORCH=1 installs only the light set
# (numpy, onnx, onnxruntime, OpenCV): the tests labelled "torch" then report as skipped.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash scripts/setup.sh --test
if [[ "${RAINDROP_TEST_NO_TORCH:-0}" == 1 ]]; then
  bash scripts/setup-tools.sh --light
else
  bash scripts/setup-tools.sh
fi
cmake -S . -B build -DRAINDROP_PYTHON="$PWD/.venv/bin/python" >&2
cmake --build build --parallel "$(nproc)" >&2
ctest --test-dir build --output-on-failure --timeout 1500
