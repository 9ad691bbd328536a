#!/usr/bin/env bash
# Installs the Debian packages kdrt's build, tests, examples, bench and plots need, when missing.
set -euo pipefail

# Every package the project needs, in one place: add new ones here.
PACKAGES=(
  cmake
  g++
  make
  pkg-config
  catch2          # the test framework (Catch2 v2)
  libassimp-dev   # mesh loading in the tests and examples
  assimp-testmodels  # Assimp's 595 test files: the mesh-loading test over all of them (tests/README.md)
  libstb-dev      # stb_image_write for the example's PNG output
  libyaml-cpp-dev # kdrt-render's scene files (YAML, with line numbers for errors)
  libopenexr-dev  # kdrt-render's OpenEXR output and --reference input (linear half or float)
  libembree-dev   # Embree 3: only kdrt-bench's --compare embree, the peer speed is stated against
  python3-matplotlib  # bench/plot_bench.py
  clang               # CI's sanitizer build and the fuzz targets (tests/fuzz)
  libclang-rt-14-dev  # Clang's ASan, UBSan and libFuzzer runtimes (clang only recommends them)
  llvm                # llvm-symbolizer: function names and lines in the sanitizers' reports
  libsdl2-dev         # kdrt-view's window (examples/view; built only when SDL2 is found)
  xvfb                # kdrt-view's tests: a virtual X server (xvfb-run)
  xauth               # xvfb-run's authority file
  xdotool             # kdrt-view's tests: key events sent to its real X11 window
)

# The cross toolchains of the platform checks (tests/platforms/run.sh), with --platforms only.
PLATFORM_PACKAGES=(
  libc6-dev-i386              # i386 with SSE2 (gcc -m32; not gcc-multilib, which the aarch64
  lib32gcc-12-dev             #   cross compiler conflicts with)
  g++-mingw-w64-x86-64-posix  # Windows, mingw-w64
  wine64                      # ... run under wine
  g++-aarch64-linux-gnu       # aarch64 (the NEON kernel)
  qemu-user                   # ... run under qemu-aarch64
  ninja-build                 # ... the cross build's generator
  emscripten                  # WebAssembly, run under node (node-acorn comes with it)
)

usage() {
  cat <<USAGE
usage: bash tools/setup.sh [--platforms] [--check] [--list] [--lock-timeout SECONDS] [--help]

Installs the Debian packages kdrt needs that are not installed yet:
  ${PACKAGES[*]}
It asks dpkg first and does nothing more when all are there, so it is quick to run again.
Otherwise it runs 'apt-get update' and 'apt-get install -y --no-install-recommends' on the
missing ones, non-interactively, through sudo unless it runs as root. Made for Debian 12.
When another package manager holds apt's or dpkg's lock (unattended upgrades on a fresh
machine), it says so and waits for it, up to --lock-timeout seconds.

  --platforms              also the cross toolchains of tests/platforms/run.sh:
                           ${PLATFORM_PACKAGES[*]}
  --check                  only report missing packages; exit 1 if any are missing
  --list                   print the package list, one per line
  --lock-timeout SECONDS   how long to wait for a held lock (default 600)
  --help                   this text
USAGE
}

check_only=0
lock_timeout=600
while [[ $# -gt 0 ]]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --list) printf '%s\n' "${PACKAGES[@]}"; exit 0 ;;
    --check) check_only=1 ;;
    --platforms) PACKAGES+=("${PLATFORM_PACKAGES[@]}") ;;
    --lock-timeout)
      if [[ $# -lt 2 || ! $2 =~ ^[0-9]+$ ]]; then
        echo "setup.sh: --lock-timeout wants a whole number of seconds, not '${2-}'" >&2; exit 2
      fi
      lock_timeout=$2; shift ;;
    *) echo "setup.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done

# The locks apt-get takes: the package lists' (update), dpkg's and the download cache's
# (install). The KDRT_SETUP_* variables are for tests/check_tools.py, which holds locks of its own.
lists_locks=("${KDRT_SETUP_LISTS_LOCK:-/var/lib/apt/lists/lock}")
install_locks=("${KDRT_SETUP_DPKG_LOCK:-/var/lib/dpkg/lock-frontend}" "${KDRT_SETUP_DPKG_LOCK_INNER:-/var/lib/dpkg/lock}"
               "${KDRT_SETUP_ARCHIVES_LOCK:-/var/cache/apt/archives/lock}")

# The process holding a lock on FILE (from /proc/locks), as "process PID (NAME)"; nothing when
# the file is absent or nobody holds it.
lock_holder() {
  local id major minor inode want pid
  id=$(stat -L -c '%Hd %Ld %i' "$1" 2>/dev/null) || return 0
  read -r major minor inode <<<"$id"
  want=$(printf '%02x:%02x:%s' "$major" "$minor" "$inode")
  pid=$(awk -v want="$want" '$2 != "->" && $6 == want { print $5; exit }' /proc/locks 2>/dev/null || true)
  if [[ -z $pid ]]; then
    return 0
  elif [[ $pid == -1 ]]; then
    echo "another process"
  else
    echo "process $pid ($(cat "/proc/$pid/comm" 2>/dev/null || echo '?'))"
  fi
}

# Waits until none of the files is locked, up to lock_timeout seconds, saying whom it waits for.
# apt-get fails at once on a held lock ("E: Could not get lock ..."); it waits too (for dpkg's
# lock) with -o DPkg::Lock::Timeout, which covers a lock taken between this check and its own.
wait_for_locks() {
  local file holder waited=0
  for file in "$@"; do
    holder=$(lock_holder "$file")
    [[ -z $holder ]] && continue
    echo "setup.sh: waiting for the lock $file, held by $holder (up to ${lock_timeout} s) ..."
    while [[ -n $holder ]]; do
      if (( waited >= lock_timeout )); then
        echo "setup.sh: cannot install: $file is still locked by $holder after ${lock_timeout} s; run setup.sh again when it is done (or give --lock-timeout)" >&2
        exit 1
      fi
      sleep 1
      waited=$((waited + 1))
      holder=$(lock_holder "$file")
    done
    echo "setup.sh: $file is free (after ${waited} s)"
  done
}

if ! command -v dpkg-query >/dev/null 2>&1; then
  echo "setup.sh: dpkg-query not found: this script is for Debian (12) and its derivatives" >&2
  exit 1
fi

missing=()
for pkg in "${PACKAGES[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null || true)
  if [[ "$status" != "install ok installed" ]]; then
    missing+=("$pkg")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "setup.sh: all ${#PACKAGES[@]} packages are installed"
  exit 0
fi
echo "setup.sh: missing: ${missing[*]}"
if [[ $check_only -eq 1 ]]; then
  exit 1
fi

as_root=()
if [[ $(id -u) -ne 0 ]]; then
  if ! command -v sudo >/dev/null 2>&1; then
    echo "setup.sh: not root and no sudo: install as root: apt-get install ${missing[*]}" >&2
    exit 1
  fi
  as_root=(sudo)
fi

apt_options=(-o "DPkg::Lock::Timeout=${lock_timeout}")
wait_for_locks "${lists_locks[@]}"
"${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get "${apt_options[@]}" update
wait_for_locks "${install_locks[@]}"
"${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get "${apt_options[@]}" install -y --no-install-recommends "${missing[@]}"
echo "setup.sh: installed ${missing[*]}"
