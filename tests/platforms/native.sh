#!/usr/bin/env bash
# The stored answers (answers.txt) and saved trees (answers.kdrt) on this x86-64 machine, in the
# builds that used to change their last bits: GCC's GNU modes and Clang with FMA (-march=native,
# which contract a * b + c unless kdrt.h stops them), C++, -O0, and i386 with SSE2. Each build
# checks every kernel the CPU has (answers.c). Run from anywhere; needs gcc, g++, clang, clang++
# and gcc -m32 (tools/setup.sh --platforms).
#   bash tests/platforms/native.sh
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
strict=(-Wall -Wextra -Werror -I "$root/include")

# name | compiler and flags (the file is compiled as C unless -x c++ is given)
builds=(
  "gcc-c99|gcc -std=c99 -O2 -pedantic"
  "gcc-gnu11-native|gcc -std=gnu11 -O3 -march=native"
  "gcc-fma-contract-fast|gcc -std=c99 -O2 -mfma -ffp-contract=fast"
  "g++-gnu++17-native|g++ -x c++ -std=gnu++17 -O2 -march=native"
  "gcc-O0|gcc -std=c99 -O0"
  "clang-c99-native|clang -std=c99 -O2 -march=native"
  "clang++-c++17-native|clang++ -x c++ -std=c++17 -O3 -march=native"
  "gcc-i386-sse2|gcc -m32 -msse2 -mfpmath=sse -std=c99 -O2"
)

failed=0 passed=0
build_one() {
  local name=$1 command=$2
  # shellcheck disable=SC2086 # the flags are words
  $command "${strict[@]}" "$here/answers.c" -o "$work/$name" -lm 2>"$work/$name.log"
}
pids=() names=()
for entry in "${builds[@]}"; do
  name=${entry%%|*} command=${entry#*|}
  build_one "$name" "$command" & pids+=($!) names+=("$name")
  # two at a time: this machine kind has 2 cores
  if (( ${#pids[@]} == 2 )); then wait "${pids[0]}" || true; pids=("${pids[@]:1}"); fi
done
wait || true
for entry in "${builds[@]}"; do
  name=${entry%%|*} command=${entry#*|}
  echo "--- $name: $command"
  if [[ ! -x $work/$name ]]; then
    echo "native.sh: $name did not build:"; cat "$work/$name.log"; failed=$((failed + 1)); continue
  fi
  if "$work/$name" "$here/answers.txt"; then passed=$((passed + 1)); else failed=$((failed + 1)); fi
done
echo "native: $passed passed, $failed failed"
(( failed == 0 ))
