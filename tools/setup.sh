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

usage() {
  cat <<USAGE
usage: bash tools/setup.sh [--check] [--list] [--help]

Installs the Debian packages kdrt needs that are not installed yet:
  ${PACKAGES[*]}
It asks dpkg first and does nothing more when all are there, so it is quick to run again.
Otherwise it runs 'apt-get update' and 'apt-get install -y --no-install-recommends' on the
missing ones, non-interactively, through sudo unless it runs as root. Made for Debian 12.

  --check   only report missing packages; exit 1 if any are missing
  --list    print the package list, one per line
  --help    this text
USAGE
}

check_only=0
for arg in "$@"; do
  case "$arg" in
    -h|--help) usage; exit 0 ;;
    --list) printf '%s\n' "${PACKAGES[@]}"; exit 0 ;;
    --check) check_only=1 ;;
    *) echo "setup.sh: unknown argument '$arg'" >&2; usage >&2; exit 2 ;;
  esac
done

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

"${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update
"${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing[@]}"
echo "setup.sh: installed ${missing[*]}"
