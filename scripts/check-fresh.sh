#!/usr/bin/env bash
# Prove that the README's two commands work on a fresh Debian 12 machine: build a minimal
# bookworm root (debootstrap --variant=minbase, plus git, which a user who clones has), clone the
# current commit into it and run `scripts/setup.sh` and then `scripts/test.sh` there, as root in
# a chroot. Needs root, debootstrap (apt-get install debootstrap) and access to a Debian mirror and
# PyPI.
#
#   scripts/check-fresh.sh                           setup.sh + test.sh (with PyTorch)
#   RAINDROP_TEST_NO_TORCH=1 scripts/check-fresh.sh  test.sh without PyTorch (passed through)
#   scripts/check-fresh.sh --record                  the same, and on PASS write .ci/fresh-checked
#   scripts/check-fresh.sh --needed                  exit 0 when the set-up files differ from
#                                                    .ci/fresh-checked (a check is due), else 1
#   scripts/check-fresh.sh --hash                    print the set-up files' hash
#
# The set-up files are what the fresh machine's result depends on: the set-up and test
# scripts, every CMakeLists.txt, cmake/, deps/, tools/requirements*.txt and
# tools/pyproject.toml. Their hash is a sha256 over the git blob ids of those files in HEAD.
# .ci/fresh-checked records the hash of the last commit that passed here; .ci/run runs the
# check when the hash differs, so a set-up change committed without a passing check is
# checked by CI, and the developer commits the new record (--record) after a passing run.
#
# Environment:
#   RAINDROP_FRESH_CACHE     cache folder (default /var/cache/raindrop-fresh): the bare root as a
#                            tarball, made once by debootstrap, and the download caches
#   RAINDROP_FRESH_MIRROR    Debian mirror (default http://deb.debian.org/debian)
#   RAINDROP_FRESH_NO_DOWNLOAD_CACHE=1
#                            do not share apt's .deb files and pip's cache between checks
#                            (by default they are kept in the cache folder: they save the
#                            downloads, never an installation; apt and pip still decide
#                            everything from the fresh root)
#   RAINDROP_FRESH_KEEP=1    keep the check's root afterwards (path printed) to look inside
#
# Taken from this machine into the root: /etc/resolv.conf, /etc/hosts, the local certificate authorities
# (/usr/local/share/ca-certificates) and /etc/pip.conf, the network's set-up, not the project's.
#
# Every check starts from a pristine copy of the bare root (unpacked from the tarball), so
# nothing installed by an earlier check can hide a missing package. The chroot's mounts live in
# a private mount namespace (unshare) and are unmounted on exit by a trap; the kernel drops them
# with the namespace in any case. The last line is `check-fresh: PASS ...` or
# `check-fresh: FAIL ...`; the exit status is 0 only on PASS.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cache="${RAINDROP_FRESH_CACHE:-/var/cache/raindrop-fresh}"
mirror="${RAINDROP_FRESH_MIRROR:-http://deb.debian.org/debian}"
suite=bookworm
bare="$cache/$suite-minbase.tar"

# ---- stage 2: inside a private mount namespace (see the end of the file) ----
if [[ "${1:-}" == --in-namespace ]]; then
  root="$2"; step="$3"
  mounts=()
  unmount_all() {
    local i
    for ((i = ${#mounts[@]} - 1; i >= 0; i--)); do
      umount "${mounts[i]}" 2>/dev/null || umount -l "${mounts[i]}" 2>/dev/null || true
    done
  }
  trap unmount_all EXIT
  mnt() { local target="${*: -1}"; mount "$@"; mounts+=("$target"); }
  mnt -t proc proc "$root/proc"
  mnt -t sysfs sysfs "$root/sys"
  mnt -t devtmpfs -o mode=0755,nosuid udev "$root/dev"
  mkdir -p "$root/dev/pts" "$root/dev/shm"
  mnt -t devpts -o newinstance,ptmxmode=0666,mode=0620 devpts "$root/dev/pts"
  mnt -t tmpfs -o mode=1777,nosuid,nodev shm "$root/dev/shm"
  if [[ "${RAINDROP_FRESH_NO_DOWNLOAD_CACHE:-0}" != 1 ]]; then
    mkdir -p "$cache/apt-archives/partial" "$cache/pip" "$root/var/cache/apt/archives" "$root/root/.cache/pip"
    mnt --bind "$cache/apt-archives" "$root/var/cache/apt/archives"
    mnt --bind "$cache/pip" "$root/root/.cache/pip"
  fi
  case "$step" in
    setup) cmd='cd /root/raindrop && scripts/setup.sh' ;;
    test)  cmd='cd /root/raindrop && scripts/test.sh' ;;
    *) echo "check-fresh: unknown step $step" >&2; exit 2 ;;
  esac
  # A clean environment, as a user logged in as root has: nothing of the caller's leaks in
  # except RAINDROP_TEST_NO_TORCH.
  chroot "$root" /usr/bin/env -i HOME=/root LANG=C.UTF-8 TERM=dumb \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
    RAINDROP_TEST_NO_TORCH="${RAINDROP_TEST_NO_TORCH:-0}" /bin/bash -c "$cmd"
  exit $?
fi

# ---- stage 1 ----
record_file="$repo/.ci/fresh-checked"
setup_hash() {  # [commit]
  git -C "$repo" rev-parse -q --verify "${1:-HEAD}^{commit}" >/dev/null \
    || { echo "check-fresh: $repo has no commit ${1:-HEAD}" >&2; exit 2; }
  git -C "$repo" ls-tree -r "${1:-HEAD}" | cut -f2- -d' ' | grep -E $'\t(CMakeLists\\.txt|.*/CMakeLists\\.txt|cmake/.*|deps/.*|scripts/(setup|setup-tools|test|fetch-onnxruntime|check-fresh)\\.sh|tools/requirements[^/]*\\.txt|tools/pyproject\\.toml)$' \
    | sha256sum | cut -d' ' -f1
}
recorded_hash() { [[ -f "$record_file" ]] && grep -v '^#' "$record_file" | awk 'NF { h = $1 } END { print h }'; }
record=0
case "${1:-}" in
  --hash) setup_hash; exit 0 ;;
  --needed)
    if [[ "$(setup_hash)" == "$(recorded_hash)" ]]; then
      echo "check-fresh: set-up files unchanged since the last recorded pass (.ci/fresh-checked): not needed"
      exit 1
    fi
    if [[ -f "$record_file" ]]; then
      echo "check-fresh: set-up files differ from the last recorded pass (.ci/fresh-checked): needed"
    else
      echo "check-fresh: no recorded pass (.ci/fresh-checked): needed"
    fi
    exit 0 ;;
  --record) record=1 ;;
  "") ;;
  -h|--help) sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "check-fresh: unknown argument $1 (see --help)" >&2; exit 2 ;;
esac
[[ $(id -u) -eq 0 ]] || { echo "check-fresh: must run as root (debootstrap, chroot, mount)" >&2; exit 2; }
command -v debootstrap >/dev/null || { echo "check-fresh: needs debootstrap (apt-get install debootstrap)" >&2; exit 2; }
commit="$(git -C "$repo" rev-parse HEAD)"
short="${commit:0:12}"
[[ -z "$(git -C "$repo" status --porcelain --untracked-files=no)" ]] \
  || echo "check-fresh: note: uncommitted changes are not checked; checking commit $short" >&2
torch=with; [[ "${RAINDROP_TEST_NO_TORCH:-0}" == 1 ]] && torch=without
mkdir -p "$cache"

t_all=$(date +%s)
timings=()
elapsed() { local s=$(($(date +%s) - $1)); printf '%dm%02ds' $((s / 60)) $((s % 60)); }
root=""
failed_step=""
finish() {
  local rc=$?
  if [[ -n "$root" && -d "$root" ]]; then
    if [[ "${RAINDROP_FRESH_KEEP:-0}" == 1 ]]; then
      echo "check-fresh: root kept at $root" >&2
    elif findmnt -rno TARGET | grep -q "^$root/"; then
      echo "check-fresh: something is still mounted under $root; not deleting it" >&2
    else
      local t=$(date +%s)
      rm -rf --one-file-system "$root"
      timings+=("cleanup $(elapsed "$t")")
    fi
  fi
  echo "check-fresh: times: ${timings[*]} total $(elapsed "$t_all")"
  if [[ $rc -eq 0 ]]; then
    echo "check-fresh: PASS: commit $short, README's setup.sh and test.sh ($torch PyTorch) in a fresh Debian 12 root"
  else
    echo "check-fresh: FAIL at ${failed_step:-set-up of the check}: commit $short ($torch PyTorch), exit $rc"
  fi
  exit $rc
}
trap finish EXIT
trap 'exit 130' INT TERM

step() {  # step NAME COMMAND...: run, time, remember a failure
  local name="$1"; shift
  local t=$(date +%s)
  echo "check-fresh: == $name" >&2
  failed_step="$name"
  "$@"
  failed_step=""
  timings+=("$name $(elapsed "$t")")
  echo "check-fresh: == $name done in $(elapsed "$t")" >&2
}

make_bare() {
  # Made once and reused; a lock keeps two checks from making it at the same time.
  exec 9>"$cache/.lock"
  flock 9
  if [[ ! -f "$bare" ]]; then
    local tmp="$cache/bare.tmp"
    rm -rf --one-file-system "$tmp"
    debootstrap --variant=minbase --include=git "$suite" "$tmp" "$mirror" >&2
    rm -rf "$tmp/var/cache/apt/archives/"*.deb
    # What an installed Debian 12 has: the release, its updates and the security archive.
    printf 'deb %s %s main\ndeb %s %s-updates main\ndeb http://deb.debian.org/debian-security %s-security main\n' \
      "$mirror" "$suite" "$mirror" "$suite" "$suite" > "$tmp/etc/apt/sources.list"
    tar -C "$tmp" --numeric-owner -cf "$bare.part" .
    mv "$bare.part" "$bare"
    rm -rf --one-file-system "$tmp"
  fi
  flock -u 9
}

unpack_root() {
  root="$(mktemp -d "$cache/check.XXXXXX")"
  tar -C "$root" --numeric-owner -xpf "$bare"
  cp /etc/resolv.conf "$root/etc/resolv.conf"
  # Every installed machine's /etc/hosts names localhost and the machine itself (Debian's
  # installer writes both); debootstrap's root has none. The chroot shares this machine's host
  # name, so it takes this machine's file, as it takes resolv.conf: without the name, torchrun's
  # workers cannot reach their rendezvous ("gai error -2" for the host name, the two-process
  # tests time out).
  if [[ -f /etc/hosts ]]; then
    cp /etc/hosts "$root/etc/hosts"
  else
    printf '127.0.0.1\tlocalhost\n127.0.1.1\t%s\n' "$(hostname)" > "$root/etc/hosts"
  fi
  # This machine's network set-up, which a fresh machine on the same network needs as well:
  # local certificate authorities (such as a TLS-inspecting proxy's; ca-certificates, when
  # setup.sh installs it, adds them to the system bundle) and pip's site configuration.
  if [[ -d /usr/local/share/ca-certificates ]]; then
    cp -r /usr/local/share/ca-certificates/. "$root/usr/local/share/ca-certificates/"
  fi
  if [[ -f /etc/pip.conf ]]; then cp /etc/pip.conf "$root/etc/pip.conf"; fi
}

clone_commit() {
  # A bundle of HEAD's history, cloned with the chroot's own git as a user clones, then the
  # commit noted at the start checked out (HEAD may have moved on while debootstrap ran).
  local git_in=(chroot "$root" /usr/bin/env -i HOME=/root PATH=/usr/bin:/bin git -c advice.detachedHead=false)
  git -C "$repo" bundle create "$root/root/raindrop.bundle" HEAD 2>/dev/null
  "${git_in[@]}" clone -q --no-checkout /root/raindrop.bundle /root/raindrop
  "${git_in[@]}" -C /root/raindrop checkout -q "$commit"
  rm "$root/root/raindrop.bundle"
  local got
  got="$(chroot "$root" /usr/bin/env -i PATH=/usr/bin:/bin git -C /root/raindrop rev-parse HEAD)"
  [[ "$got" == "$commit" ]] || { echo "check-fresh: the clone is at $got, not $commit" >&2; return 1; }
}

in_chroot() { unshare --mount --propagation private bash "${BASH_SOURCE[0]}" --in-namespace "$root" "$1"; }

step "bare-root" make_bare
step "fresh-copy" unpack_root
step "clone" clone_commit
step "setup.sh" in_chroot setup
step "test.sh" in_chroot test
if ((record)); then
  {
    echo "# sha256 of the set-up files (scripts/check-fresh.sh --hash) at the last commit that passed"
    echo "# scripts/check-fresh.sh; .ci/run runs the check when they differ. Written by --record."
    echo "$(setup_hash "$commit") $commit $(date -u +%Y-%m-%d) $torch-torch"
  } > "$record_file"
  echo "check-fresh: recorded in .ci/fresh-checked (commit it)" >&2
fi
