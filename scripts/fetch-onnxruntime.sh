#!/usr/bin/env bash
# Obtain ONNX Runtime for Debian 12 into DEST (default: build/_deps/onnxruntime):
#   DEST/lib/libonnxruntime.so.<ver>  (+ libonnxruntime.so symlink)  from the PyPI wheel
#   DEST/include/onnxruntime/*.h                                    from trixie's -dev package
# With --gpu (default DEST: build/_deps/onnxruntime-gpu): the library from the onnxruntime-gpu
# wheel instead, with its CUDA provider libraries beside it (DEST/lib/libonnxruntime_providers_
# {shared,cuda}.so), which need CUDA 13, cuDNN 9 and the NVIDIA driver at run time.
# Versions and checksums are pinned in deps/onnxruntime.env. Idempotent: does nothing when
# DEST/.complete matches the pins. Nothing is installed system-wide.
#   usage: scripts/fetch-onnxruntime.sh [--gpu] [DEST]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=../deps/onnxruntime.env
source "$here/deps/onnxruntime.env"
gpu=0
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
  sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
if [[ "${1:-}" == "--gpu" ]]; then
  gpu=1
  shift
fi
if ((gpu)); then
  package=onnxruntime-gpu wheel="$ORT_GPU_WHEEL" wheel_sha256="$ORT_GPU_WHEEL_SHA256"
  dest="${1:-$here/build/_deps/onnxruntime-gpu}"
else
  package=onnxruntime wheel="$ORT_WHEEL" wheel_sha256="$ORT_WHEEL_SHA256"
  dest="${1:-$here/build/_deps/onnxruntime}"
fi
[[ $dest == -* ]] && { echo "fetch-onnxruntime: unknown option '$dest' (usage: scripts/fetch-onnxruntime.sh [--gpu] [DEST])" >&2; exit 2; }
# DEST is emptied before the new files go in: only a folder this script filled before (its
# .complete stamp, whatever version) or an empty or new one. Any other folder a user names
# may hold their own files (a DEST of ~ or /usr/local would otherwise be wiped).
if [[ -e $dest && ! -f $dest/.complete && ! -f $dest/.fetching ]] && [[ ! -d $dest || -n $(ls -A "$dest" 2>/dev/null) ]]; then
  echo "fetch-onnxruntime: '$dest' exists and was not made by this script (no .complete or .fetching in it); give a new or empty folder" >&2
  exit 1
fi
stamp="$ORT_LIB_VERSION/$ORT_HEADERS_DEB_VERSION"
((gpu)) && stamp="gpu-$stamp"
soname_links() {
  # libonnxruntime.so (for linking) and libonnxruntime.so.1 (its SONAME, what programs load).
  ln -sf "libonnxruntime.so.$ORT_LIB_VERSION" "$dest/lib/libonnxruntime.so"
  ln -sf "libonnxruntime.so.$ORT_LIB_VERSION" "$dest/lib/libonnxruntime.so.1"
}
if [[ -f "$dest/.complete" && "$(cat "$dest/.complete")" == "$stamp" ]]; then
  soname_links
  exit 0
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
echo "fetch-onnxruntime: library $ORT_LIB_VERSION (PyPI wheel $package), headers $ORT_HEADERS_DEB_VERSION (Debian trixie)" >&2

# 1. The library, from the wheel. --python-version/--platform make pip pick exactly the pinned file.
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.11 \
  --platform manylinux_2_28_x86_64 "$package==$ORT_LIB_VERSION" -d "$work/wheel" >&2
echo "$wheel_sha256  $work/wheel/$wheel" | sha256sum --check --quiet -

# 2. The headers, from trixie, with a private source list, state and cache (the system's apt
#    configuration is not touched).
apt_opts=(-o "Dir::Etc::sourcelist=$work/apt/sources.list" -o "Dir::Etc::sourceparts=-"
          -o "Dir::State::Lists=$work/apt/lists" -o "Dir::Cache=$work/apt/cache"
          -o "Debug::NoLocking=1" -o "APT::Sandbox::User=root")
mkdir -p "$work/apt/lists/partial" "$work/apt/cache/archives/partial"
echo "deb http://deb.debian.org/debian trixie main" > "$work/apt/sources.list"
apt-get "${apt_opts[@]}" -qq update >&2
(cd "$work" && apt-get "${apt_opts[@]}" -qq download "libonnxruntime-dev=$ORT_HEADERS_DEB_VERSION" >&2)
echo "$ORT_HEADERS_DEB_SHA256  $work/$ORT_HEADERS_DEB" | sha256sum --check --quiet -

rm -rf "$dest" && mkdir -p "$dest/lib" "$dest/include" && : >"$dest/.fetching"  # ours, even if cut short
python3 - "$work/wheel/$wheel" "$dest/lib" "$ORT_LIB_VERSION" "$gpu" <<'PY'
import sys, zipfile, os
whl, out, ver, gpu = sys.argv[1:]
names = [f"onnxruntime/capi/libonnxruntime.so.{ver}"]
if gpu == "1":  # loaded by libonnxruntime from its own folder when --device cuda asks for them
    names += ["onnxruntime/capi/libonnxruntime_providers_shared.so", "onnxruntime/capi/libonnxruntime_providers_cuda.so"]
with zipfile.ZipFile(whl) as z:
    for name in names:
        with open(os.path.join(out, os.path.basename(name)), "wb") as f:
            f.write(z.read(name))
PY
soname_links
dpkg -x "$work/$ORT_HEADERS_DEB" "$work/deb"
cp -r "$work/deb/usr/include/onnxruntime" "$dest/include/"
echo "$stamp" > "$dest/.complete"
echo "fetch-onnxruntime: ready in $dest" >&2
