#!/usr/bin/env bash
# kdrt on Windows, built by mingw-w64 GCC and run under wine: the smoke tests, the examples that
# need only the header, and kernel_report.c, which checks that a default tree runs the AVX-512 or
# AVX2 kernel where this CPU has it (wine passes the CPU's features through), a scalar-flagged one
# the scalar kernel, and that all of them give the same answers bit for bit.
#   tests/platforms/windows.sh
# Compiled as CMake compiles them (the Release build's -O3 -DNDEBUG, tests/CMakeLists.txt's and
# examples/CMakeLists.txt's warnings, as errors), linked with -static so that wine needs no DLL
# path. Uses x86_64-w64-mingw32-gcc-posix and -g++-posix, /usr/lib/wine/wine64 and wineserver
# (KDRT_MINGW_CC, KDRT_MINGW_CXX, KDRT_WINE, KDRT_WINESERVER override them). Exits non-zero on any
# failure.
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
cc=${KDRT_MINGW_CC:-x86_64-w64-mingw32-gcc-posix}
cxx=${KDRT_MINGW_CXX:-x86_64-w64-mingw32-g++-posix}
wine=${KDRT_WINE:-/usr/lib/wine/wine64}
wineserver=${KDRT_WINESERVER:-/usr/lib/wine/wineserver}
start=$SECONDS

work=$(mktemp -d "${TMPDIR:-/tmp}/kdrt-windows.XXXXXX")
export WINEPREFIX="$work/prefix" WINEDEBUG=-all
# No Mono or Gecko: the prefix is made without asking for them.
export WINEDLLOVERRIDES="mscoree,mshtml="
wineserver_started=0
cleanup() {
    if [ "$wineserver_started" = 1 ]; then "$wineserver" -k 2>/dev/null || true; fi
    rm -rf "$work"
}
trap cleanup EXIT

# The prefix takes ~10-20 s to make on the first start: made while the programs compile, with one
# wineserver kept alive (-p) for all the runs, so that each run then starts at once.
mkdir -p "$WINEPREFIX"
echo "+ $wineserver -p; $wine wineboot --init (WINEPREFIX=$WINEPREFIX)"
"$wineserver" -p
wineserver_started=1
( "$wine" wineboot --init >"$work/wineboot.log" 2>&1; echo $? >"$work/wineboot.status" ) &

warnings=(-Wall -Wextra -pedantic -Werror)              # kdrt_warnings (CMakeLists.txt)
strict=(-Wconversion -Wsign-conversion -Wshadow)        # kdrt_strict_conversions (tests/)
release=(-O3 -DNDEBUG)                                  # CMAKE_BUILD_TYPE=Release
include=(-I"$root/include")

# compile NAME COMPILER FLAGS... : NAME.exe in $work, in the background, two at a time (the
# machine's two cores); a failure leaves NAME.failed.
compiles=()
compile() {
    local name=$1 pid running
    shift
    echo "+ $* -o $name.exe"
    ( cd "$work" && "$@" -o "$name.exe" >"$name.build.log" 2>&1 ) || {
        cat "$work/$name.build.log" >&2
        touch "$work/$name.failed"
    } &
    compiles+=($!)
    while :; do
        running=0
        for pid in "${compiles[@]}"; do if kill -0 "$pid" 2>/dev/null; then running=$((running + 1)); fi; done
        [ "$running" -lt 2 ] && break
        sleep 0.1
    done
}

compile smoke_c99 "$cc" -std=c99 "${release[@]}" "${warnings[@]}" "${strict[@]}" "${include[@]}" \
    "$root/tests/smoke_c99.c" -static
compile smoke_stats "$cc" -std=c99 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/tests/smoke_stats.c" -static
compile smoke_cpp11 "$cxx" -std=c++11 "${release[@]}" "${warnings[@]}" "${strict[@]}" "${include[@]}" \
    "$root/tests/smoke_cpp11.cpp" -static
compile minimal "$cc" -std=c99 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/examples/minimal.c" -static
compile engine "$cxx" -std=c++17 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/examples/engine.cpp" -static -pthread
compile instances "$cxx" -std=c++17 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/examples/instances.cpp" -static
# kernel_report with kdrt's assertions on (no NDEBUG), at the strict warnings.
compile kernel_report "$cc" -std=c99 -O2 "${warnings[@]}" "${strict[@]}" "${include[@]}" \
    "$root/tests/platforms/kernel_report.c" -static
for pid in "${compiles[@]}"; do wait "$pid" || true; done # each leaves its .failed
if compgen -G "$work/*.failed" >/dev/null; then
    echo "windows.sh: FAILED: these did not compile: $(cd "$work" && ls -- *.failed | sed 's/\.failed$//' | tr '\n' ' ')" >&2
    exit 1
fi
# 0 warnings (the warnings are errors, so a warning failed the build above; this says so plainly).
if grep -l "warning:" "$work"/*.build.log >/dev/null 2>&1; then
    echo "windows.sh: FAILED: warnings in $(grep -l "warning:" "$work"/*.build.log | tr '\n' ' ')" >&2
    exit 1
fi
echo "built in $((SECONDS - start)) s"

wait # wineboot too
if [ "$(cat "$work/wineboot.status" 2>/dev/null)" != 0 ]; then
    cat "$work/wineboot.log" >&2
    echo "windows.sh: FAILED: wineboot could not make the prefix" >&2
    exit 1
fi
echo "wine prefix ready at $((SECONDS - start)) s"

failures=0
# run NAME EXPECTED... : runs NAME.exe under wine; it must exit 0 and its output (CRLF made LF)
# must hold each EXPECTED line (a grep -E pattern).
run() {
    local name=$1 status=0 pattern
    shift
    echo "+ $wine $name.exe"
    (cd "$work" && "$wine" "$name.exe") >"$work/$name.out" 2>"$work/$name.err" || status=$?
    tr -d '\r' <"$work/$name.out" >"$work/$name.txt"
    sed 's/^/    /' "$work/$name.txt"
    if [ "$status" != 0 ]; then
        tr -d '\r' <"$work/$name.err" | sed 's/^/    /' >&2
        echo "windows.sh: FAILED: $name.exe exited with $status" >&2
        failures=$((failures + 1))
        return
    fi
    for pattern in "$@"; do
        if ! grep -Eq -- "$pattern" "$work/$name.txt"; then
            echo "windows.sh: FAILED: $name.exe printed no line matching: $pattern" >&2
            failures=$((failures + 1))
        fi
    done
}

run smoke_c99
run smoke_stats
run smoke_cpp11
run minimal "^hit triangle 0 at t = 1"
run engine "^built: 6914 triangles, [1-9][0-9]* tasks on the job system" \
    "^[1-9][0-9]* of 1536 pixels hit, [1-9][0-9]* bounces hit" "^after kdrt_tree_free: 0 bytes in use$"
run instances "^all checks passed$"

# The kernels this CPU should run, from Linux's view of it: AVX-512 where it has AVX512F (and
# AVX2), else AVX2 where it has AVX2, else scalar.
flags=$(grep -m1 '^flags' /proc/cpuinfo || true)
has() { case " ${flags#*:} " in *" $1 "*) return 0 ;; *) return 1 ;; esac; }
default_kernel=scalar avx2_kernel=scalar
if has avx2; then
    default_kernel=avx2 avx2_kernel=avx2
    if has avx512f; then default_kernel=avx512; fi
fi
echo "this CPU: the default tree should run the $default_kernel kernel"
run kernel_report "^kernel default: $default_kernel " "^kernel KDRT_BUILD_AVX2_KERNEL: $avx2_kernel " \
    "^kernel KDRT_BUILD_SCALAR_KERNEL: scalar " "^kernel_report: all checks passed$"

echo "windows.sh: $((SECONDS - start)) s in all"
if [ "$failures" != 0 ]; then
    echo "windows.sh: FAILED: $failures checks" >&2
    exit 1
fi
echo "windows.sh: all passed"
