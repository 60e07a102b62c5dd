#!/usr/bin/env bash
# Set up the Python tools (tools/): a virtual environment at the repo root (.venv, or
# $RAINDROP_VENV) with the pinned requirements and `pip install -e tools`.
#
#   scripts/setup-tools.sh            full set: training, export, reference, metrics, tests
#   scripts/setup-tools.sh --light    no torch: reference pipeline, metrics, evaluation and
#                                     the `pytest -m "not torch"` tests (also RAINDROP_TOOLS_LIGHT=1)
#
# Idempotent: a stamp in the venv records what was installed (hash of the requirement file
# and pyproject); when it matches and the package imports from this checkout, nothing runs.
# A full install satisfies a light request. Python: $PYTHON or python3 (3.11).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${RAINDROP_VENV:-$root/.venv}"
python="${PYTHON:-python3}"
mode=full
[[ "${RAINDROP_TOOLS_LIGHT:-0}" == 1 ]] && mode=light
for arg in "$@"; do
  case "$arg" in
    --light) mode=light ;;
    --full) mode=full ;;
    -h|--help) sed -n '2,12p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "setup-tools: unknown argument $arg (use --light, --full or --help)" >&2; exit 2 ;;
  esac
done

req_for() { [[ "$1" == light ]] && echo "$root/tools/requirements-light.txt" || echo "$root/tools/requirements.txt"; }
stamp_for() { echo "$venv/.raindrop-tools-$1.stamp"; }
want_for() { cat "$(req_for "$1")" "$root/tools/pyproject.toml" | sha256sum | cut -d' ' -f1; }

installed_here() {
  # the package imports, and from this checkout (not from another clone's editable install)
  local file
  file="$("$venv/bin/python" -c 'import raindrop_tools, os; print(os.path.realpath(raindrop_tools.__file__))' 2>/dev/null)" || return 1
  [[ "$file" == "$(realpath "$root/tools/raindrop_tools/__init__.py")" ]]
}

up_to_date() {
  local m="$1"
  [[ -x "$venv/bin/python" && -f "$(stamp_for "$m")" && "$(cat "$(stamp_for "$m")")" == "$(want_for "$m")" ]] && installed_here
}

if up_to_date "$mode" || { [[ "$mode" == light ]] && up_to_date full; }; then
  exit 0
fi

# Only into an environment this script made (its marker, or a stamp of an earlier run) or a new
# one: pip would otherwise replace the packages of someone else's environment (RAINDROP_VENV
# pointing at a project's venv: its torch, numpy, ... changed to our pins), and `python -m venv`
# would write into a folder of the user's files.
marker="$venv/.raindrop-tools-venv"
if [[ -e "$venv" && ! -e "$marker" ]] && ! compgen -G "$venv/.raindrop-tools-*.stamp" >/dev/null; then
  if [[ -e "$venv/pyvenv.cfg" ]]; then
    echo "setup-tools: $venv is a Python environment this script did not make; installing would change its packages." \
         "Choose a new folder for RAINDROP_VENV, or create $marker to allow it" >&2
    exit 1
  elif [[ ! -d "$venv" ]] || [[ -n "$(ls -A "$venv")" ]]; then
    echo "setup-tools: $venv exists and is not an empty folder or a Python environment; choose a new folder for RAINDROP_VENV" >&2
    exit 1
  fi
fi
if [[ ! -x "$venv/bin/python" ]]; then
  echo "setup-tools: creating $venv with $("$python" --version 2>&1)" >&2
  mkdir -p "$venv" && touch "$marker"  # first, so that a stopped creation can be resumed
  "$python" -m venv "$venv"
fi
touch "$marker"
echo "setup-tools: installing the $mode set from $(basename "$(req_for "$mode")") into $venv" >&2
"$venv/bin/python" -m pip install -q -r "$(req_for "$mode")"
# Editable install of the package itself; its dependencies came from the pinned file.
# Without build isolation when the venv's setuptools can build it (no download needed).
if ! "$venv/bin/python" -m pip install -q --no-deps --no-build-isolation -e "$root/tools" 2>/dev/null; then
  "$venv/bin/python" -m pip install -q --no-deps -e "$root/tools"
fi
installed_here || { echo "setup-tools: raindrop_tools does not import from $root/tools" >&2; exit 1; }
want_for "$mode" > "$(stamp_for "$mode")"
echo "setup-tools: done ($mode)" >&2
