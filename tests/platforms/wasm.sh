#!/usr/bin/env bash
# The header compiled to WebAssembly with emscripten and run under node: the smoke tests
# (tests/smoke_c99.c, smoke_cpp11.cpp, smoke_stats.c), the header-only examples
# (examples/minimal.c, instances.cpp, and engine.cpp, whose std::threads run as emscripten
# pthreads in node's workers), the stored answers' checker (tests/platforms/answers.c, which
# also loads the trees saved on x86-64, answers.kdrt) where it exists, and kernel_speed.c, which
# traces the same 200,000 rays with the SIMD128 kernel and the scalar kernel and compares their
# answers bit for bit; each twice, built without and with -msimd128 (the SIMD128 kernel), but the
# examples once, as emcc builds them by default (without -msimd128; the smoke tests, the answers
# and kernel_speed run the SIMD128 kernel), at -O2 with the strict warnings.
#   bash tests/platforms/wasm.sh [WORK_DIR]      (default build-wasm)
# Needs emcc (emscripten 3.1.6 here) and node. Under a minute on 2 cores.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
work=${1:-build-wasm}
mkdir -p "$work"
# Debian's emcc finds its acorn through NODE_PATH when node is not Debian's own.
export NODE_PATH=${NODE_PATH:-/usr/share/nodejs}
start=$SECONDS
step() { printf '=== %s (at %ds)\n' "$*" "$((SECONDS - start))"; }

strict=(-O2 -Wall -Wextra -pedantic -Werror -Iinclude)
conversions=(-Wconversion -Wsign-conversion -Wshadow)
# A node program, its .wasm inside the .js: node 20's fetch cannot load a .wasm by path, which
# the default asynchronous loading tries; EXIT_RUNTIME so that node exits when main returns.
link=(-sENVIRONMENT=node -sSINGLE_FILE=1 -sEXIT_RUNTIME=1 -sALLOW_MEMORY_GROWTH=1)
# shellcheck disable=SC2054  # node,worker is one emcc setting
threads=(-pthread -sENVIRONMENT=node,worker -sSINGLE_FILE=1 -sEXIT_RUNTIME=1 -sPTHREAD_POOL_SIZE=8
         -sINITIAL_MEMORY=268435456)

programs=(smoke_c99 smoke_cpp11 smoke_stats minimal instances engine kernel_speed)
examples=(minimal instances engine)
# The flavours PROGRAM is built in.
flavours_of() { if [[ " ${examples[*]} " == *" $1 "* ]]; then echo scalar; else echo scalar simd128; fi; }
[[ -f tests/platforms/answers.c ]] && programs+=(answers)
build_one() { # PROGRAM FLAVOUR (scalar or simd128)
  local simd=() out="$work/$1-$2.js"
  [[ $2 == simd128 ]] && simd=(-msimd128)
  case $1 in
    smoke_c99 | smoke_stats) emcc -std=c99 "${strict[@]}" "${conversions[@]}" "${simd[@]}" "${link[@]}" "tests/$1.c" -o "$out" ;;
    smoke_cpp11) em++ -std=c++11 "${strict[@]}" "${conversions[@]}" "${simd[@]}" "${link[@]}" tests/smoke_cpp11.cpp -o "$out" ;;
    minimal) emcc -std=c99 "${strict[@]}" "${simd[@]}" "${link[@]}" examples/minimal.c -o "$out" ;;
    instances) em++ -std=c++17 "${strict[@]}" "${simd[@]}" "${link[@]}" examples/instances.cpp -o "$out" ;;
    engine) em++ -std=c++17 "${strict[@]}" "${simd[@]}" "${threads[@]}" examples/engine.cpp -o "$out" ;;
    kernel_speed) emcc -std=c99 "${strict[@]}" "${conversions[@]}" "${simd[@]}" "${link[@]}" tests/platforms/kernel_speed.c -o "$out" ;;
    # NODERAWFS: it reads answers.txt and answers.kdrt from the host's file system
    answers) emcc -std=c99 "${strict[@]}" "${simd[@]}" "${link[@]}" -sNODERAWFS=1 tests/platforms/answers.c -o "$out" ;;
  esac
}

step "build, two at a time"
jobs_running=0 failed=0
for program in "${programs[@]}"; do
  for flavour in $(flavours_of "$program"); do
    build_one "$program" "$flavour" &
    if (( ++jobs_running == 2 )); then wait -n || failed=1; jobs_running=$((jobs_running - 1)); fi
  done
done
while (( jobs_running > 0 )); do wait -n || failed=1; jobs_running=$((jobs_running - 1)); done
(( failed == 0 )) || { echo "wasm.sh: a build failed" >&2; exit 1; }

for flavour in scalar simd128; do
  step "run under node: $flavour"
  for program in smoke_c99 smoke_cpp11 smoke_stats minimal instances engine; do
    [[ " $(flavours_of "$program") " == *" $flavour "* ]] || continue
    node "$work/$program-$flavour.js" >"$work/$program-$flavour.out" ||
      { cat "$work/$program-$flavour.out"; echo "wasm.sh: $program ($flavour) failed" >&2; exit 1; }
    echo "$program ($flavour): passed"
  done
  # with every kernel the build has: scalar, and in the -msimd128 build SIMD128 too; the built
  # trees, then the saved ones (answers.kdrt)
  if [[ -f tests/platforms/answers.c ]]; then node "$work/answers-$flavour.js" tests/platforms/answers.txt; fi
done

step "the SIMD128 kernel against the scalar kernel, 200,000 rays"
# The scalar build has the scalar kernel alone; the SIMD128 build runs both and compares them.
node "$work/kernel_speed-scalar.js" 200000 scalar | tee "$work/speed-scalar.out"
node "$work/kernel_speed-simd128.js" 200000 both | tee "$work/speed-simd128.out"
checksums=$(sed -n 's/.*checksum \([0-9a-f]*\).*/\1/p' "$work"/speed-*.out | sort -u | wc -l)
if (( checksums != 1 )); then
  echo "wasm.sh: the builds' answers differ" >&2
  exit 1
fi
step "done"
