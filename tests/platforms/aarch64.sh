#!/usr/bin/env bash
# The header on aarch64, where its NEON kernel runs: the core Catch2 suites (kdrt_tests, whose
# trees run the NEON kernel, and kdrt_scalar_tests, built with KDRT_NO_SIMD), the smoke tests and,
# where it exists, the stored answers' checker (tests/platforms/answers.c) with the NEON and the
# scalar kernel, cross-compiled (tests/platforms/aarch64-toolchain.cmake) and run under qemu-user.
#   bash tests/platforms/aarch64.sh [BUILD_DIR]      (default build-aarch64)
# Also compiles the implementation at -O0 and -O2 with the strict warnings as C99 and C++11, and
# checks that its kernels hold no fused multiply-add (fmla, fmls, fmadd, ...) under
# -ffp-contract=off and =fast, with GCC and with Clang. Under qemu only the tests whose answers
# depend on the kernel run, on fewer random rays (KDRT_TEST_RAYS) than the native build, so that
# the whole script takes about 3 minutes on 2 cores. Needs: cmake, ninja, qemu-user, Catch2 2
# (header-only) and aarch64-linux-gnu-g++ or clang (KDRT_AARCH64_COMPILER=gcc|clang picks one).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
build=${1:-build-aarch64}
qemu=(qemu-aarch64 -L /usr/aarch64-linux-gnu)
start=$SECONDS
step() { printf '=== %s (at %ds)\n' "$*" "$((SECONDS - start))"; }

step "configure and build the core suites for aarch64"
# Under qemu, the tests below run at KDRT_TEST_RAYS=2000 random rays a scene, and each gets its
# seconds under qemu on 2 cores as its COST, so that ctest starts the longest first and one run
# keeps both cores busy to the end: a file of properties that ctest reads once it has listed the
# tests (KDRT_TEST_PROPERTIES_FILE, tests/CMakeLists.txt).
mkdir -p "$build"
properties="$(cd "$build" && pwd)/qemu-test-properties.cmake"
{
  echo "# Written by tests/platforms/aarch64.sh: the costs of the tests it runs under qemu."
  while IFS='|' read -r cost name; do
    echo "set_tests_properties([==[$name]==] PROPERTIES COST $cost)"
  done <<'TESTS'
32|kernels: the SIMD and scalar kernels answer every ray bit for bit alike
16|hard sets: every answer agrees with the oracle and every leaf size answers as leaf size 0
16|scalar:spheres agree with the reference
15|spheres agree with the reference
14|k nearest: every hit of small meshes, against a tree per triangle
12|watertight: no ray aimed at a vertex or an edge slips through a closed mesh
9|query: culled faces are those the double-precision normal says, both tests
7|cells: a ray started from any cell gets the root walk's answer, bit for bit
6|batch: coherent and incoherent rays on generated meshes, bit for bit as one by one
6|batch: packets with an odd ray, mixed signs, special parts, per-lane ranges, split planes and hints
6|scalar:random triangle soups agree with the reference
5|batch: scenes of meshes, and of meshes and instances, as the single scene calls
5|scalar:height field grids agree with the reference
5|random triangle soups agree with the reference
4|height field grids agree with the reference
1|batch: several threads batching on one tree and one scene at once get the single-ray answers
1|batch: NULL arguments give misses and 0, and count 0 writes nothing
1|batch: coherent and incoherent rays on the shared meshes
TESTS
} >"$properties"
# The implementation (C) at -O2, where the kernels are; the suites (C++) at -O1, which builds in
# far less time than -O3 and runs them about as fast under qemu; and of the core suites only the
# files whose tests run below (KDRT_CORE_SUITES; test_kernels.cpp is always built).
suites="test_reference.cpp;test_watertight.cpp;test_queries.cpp;test_cells.cpp;test_batch.cpp"
cmake -S . -B "$build" -G Ninja -DCMAKE_TOOLCHAIN_FILE=tests/platforms/aarch64-toolchain.cmake \
  -DKDRT_CORE_TESTS_ONLY=ON -DKDRT_CORE_SUITES="$suites" -DCMAKE_BUILD_TYPE=Release \
  -DKDRT_TEST_PROPERTIES_FILE="$properties" \
  -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG" -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" >/dev/null
cmake --build "$build" -j2

step "the implementation's object code: strict warnings, no fused multiply-adds in the kernels"
objects="$build/platform-checks"
mkdir -p "$objects"
printf '#define KDRT_IMPLEMENTATION\n#include "kdrt.h"\n' >"$objects/implementation.c"
strict=(-Wall -Wextra -pedantic -Werror -Wconversion -Wsign-conversion -Wshadow -Iinclude)
compilers=()
command -v aarch64-linux-gnu-gcc >/dev/null && compilers+=(gcc)
command -v clang >/dev/null && [[ -d /usr/aarch64-linux-gnu/include ]] && compilers+=(clang)
# The C compiler of the CMake build, for the programs built here.
compiler_c=(aarch64-linux-gnu-gcc)
[[ ${compilers[0]} == gcc ]] || compiler_c=(clang --target=aarch64-linux-gnu)
# The objects first, two compilers at a time (each compile is one process); then their checks.
compile_failed=0
for cc in "${compilers[@]}"; do
  if [[ $cc == gcc ]]; then c=(aarch64-linux-gnu-gcc) cxx=(aarch64-linux-gnu-g++)
  else c=(clang --target=aarch64-linux-gnu) cxx=(clang++ --target=aarch64-linux-gnu); fi
  compiles=(
    "${c[*]} -std=c99 -O0 ${strict[*]} -c $objects/implementation.c -o $objects/$cc-O0.o"
    "${cxx[*]} -std=c++11 -x c++ -O0 ${strict[*]} -c $objects/implementation.c -o $objects/$cc-O0-cpp.o"
    "${c[*]} -std=c99 -O2 -ffp-contract=off ${strict[*]} -c $objects/implementation.c -o $objects/$cc-O2-off.o"
    "${c[*]} -std=c99 -O2 -ffp-contract=fast ${strict[*]} -c $objects/implementation.c -o $objects/$cc-O2-fast.o")
  for command in "${compiles[@]}"; do
    # shellcheck disable=SC2086  # a command line of words without spaces of their own
    { echo "+ $command"; $command; } &
    if (( $(jobs -rp | wc -l) >= 2 )); then wait -n || compile_failed=1; fi
  done
done
while (( $(jobs -rp | wc -l) > 0 )); do wait -n || compile_failed=1; done
if (( compile_failed )); then echo "aarch64.sh: the implementation did not compile cleanly (above)" >&2; exit 1; fi
for cc in "${compilers[@]}"; do
  for contract in off fast; do
    object="$objects/$cc-O2-$contract.o"
    # The kernel is inlined into the walks (Clang) or stays in kdrt__block_*_x4 (GCC): no vector
    # fused multiply-add anywhere, and none in the block tests. The scalar kernel's own fusing
    # under -ffp-contract=fast is the compiler's, which KERNELS allows for; so is the builders'
    # (Clang vectorizes their double-precision areas), which shapes trees, never answers, and a
    # load's (the same areas, inlined into kdrt__load_tree), which gives its stats' sah_cost alone.
    # The closest-point walk's distances are in double, outside the kernels: under
    # -ffp-contract=fast Clang ignores the header's contract(off) (PLATFORMS: leave that flag off
    # this file) and fuses them there, which -ffp-contract=off, the checked case, does not.
    fused=$(aarch64-linux-gnu-objdump -d --no-show-raw-insn "$object" | awk '
      /^[0-9a-f]+ <.*>:$/ { fn = $2 }
      /\t(fmla|fmls|fmadd|fmsub|fnmadd|fnmsub|fnmla|fnmls)\t/ {
        if ($0 ~ /v[0-9]+\./ || fn ~ /_x4/) print fn, $0 }' | grep -v -E '<kdrt__(build_tree|split_refs|surface|level_subtree|level_split|load_tree|check_nodes|closest_walk|closest_finish)>' || true)
    kernels=$(aarch64-linux-gnu-objdump -d --no-show-raw-insn "$object" | grep -c -E 'fmul\s+v[0-9]+\.(4s|2d)' || true)
    if [[ -n $fused ]]; then
      echo "aarch64.sh: $cc -ffp-contract=$contract fused the kernel's multiplies:" >&2
      echo "$fused" >&2
      exit 1
    fi
    if [[ $kernels -eq 0 ]]; then
      echo "aarch64.sh: $cc -ffp-contract=$contract: no NEON multiplies found, so no NEON kernel compiled" >&2
      exit 1
    fi
    echo "$cc -ffp-contract=$contract: $kernels NEON multiplies, none fused"
  done
done

step "the core suites' kernel and answer tests and the smoke tests under qemu"
# All of the core suites take about half an hour under qemu on 2 cores, so this runs the tests
# whose answers depend on the kernel: the NEON kernel against the scalar one bit for bit, the
# reference suites, the watertight and hard sets against the oracle, queries (culled faces come
# from the kernel's determinant), k nearest, start cells and batches against single rays (one ray
# at a time on this kernel: the coherent, packet and scene batches, not every builder's or every
# query flag's, which the native build compares), at 2,000 random rays a scene (the native
# build's 100,000 look for rare wrong answers); and the scalar suite's kernel test and reference
# suites. Left out: the builder's tests (allocation failures, the parallel build, hostile and
# far geometry, errors, inspection, scenes), saving and loading, closest point and overlap (whose
# code has no NEON kernel) and the batches' allocation count, which do not depend on the kernel:
# their files are not built, and the native build runs them all.
# One ctest run for both suites, the longest tests first.
kernel_tests='^(kernels: |random triangle soups|height field grids|spheres agree|watertight: |hard sets: |query: |k nearest: every hit of small|cells: a ray started|batch: (coherent|packets|scenes|NULL|several)|smoke_|stored_answers)'
scalar_tests='^scalar: ?(kernels: |random triangle soups|height field grids|spheres agree)'
KDRT_TEST_RAYS=2000 ctest --test-dir "$build" -j2 --output-on-failure --no-tests=error -R "$kernel_tests|$scalar_tests"

if [[ -f tests/platforms/answers.c ]]; then
  step "the stored answers (tests/platforms/answers.txt) and saved trees (answers.kdrt), NEON and scalar"
  # answers.c checks the file with every kernel the build has: here the default (NEON) and
  # KDRT_BUILD_SCALAR_KERNEL; the KDRT_NO_SIMD build has the scalar kernel alone. Then it loads
  # the trees saved on x86-64 beside it and checks them the same way.
  # The two builds at once, then their runs one after the other (each prints its lines).
  "${compiler_c[@]}" -std=c99 -O2 "${strict[@]}" tests/platforms/answers.c -o "$objects/answers" -lm &
  "${compiler_c[@]}" -std=c99 -O2 "${strict[@]}" -DKDRT_NO_SIMD tests/platforms/answers.c -o "$objects/answers-no-simd" -lm &
  answers_failed=0
  wait -n || answers_failed=1
  wait -n || answers_failed=1
  if (( answers_failed )); then echo "aarch64.sh: tests/platforms/answers.c did not compile cleanly (above)" >&2; exit 1; fi
  "${qemu[@]}" "$objects/answers" tests/platforms/answers.txt
  "${qemu[@]}" "$objects/answers-no-simd" tests/platforms/answers.txt
fi
step "done"
