#!/usr/bin/env bash
# kdrt on Windows, run under wine: the smoke tests, the examples that need only the header, the
# stored answers and saved trees (answers.c) and kernel_report.c, built by mingw-w64 GCC;
# kernel_report by clang for mingw-w64 too; and kernel_report linked with kdrt's implementation
# compiled by clang for MSVC's target (as clang-cl compiles it, and in cl.exe's macro set, as
# msvc.sh compiles them), which runs its cpuid check. kernel_report checks that a default tree
# runs the AVX-512 or AVX2 kernel where this CPU has it (wine passes the CPU's features through),
# an AVX2-flagged one AVX2, a scalar-flagged one the scalar kernel, and that all answer alike bit
# for bit.
#   tests/platforms/windows.sh
# Compiled as CMake compiles them (the Release build's -O3 -DNDEBUG, tests/CMakeLists.txt's and
# examples/CMakeLists.txt's warnings, as errors; kernel_report at -O2 with assertions on),
# linked with -static so that wine needs no DLL path. Uses x86_64-w64-mingw32-gcc-posix,
# -g++-posix and -nm, clang, /usr/lib/wine/wine64 and wineserver (KDRT_MINGW_CC, KDRT_MINGW_CXX,
# KDRT_MINGW_NM, KDRT_CLANG, KDRT_WINE, KDRT_WINESERVER override them), and CC (or cc) for a
# native kernel_report, whose answers each Windows build must give bit for bit. Prints what it
# runs; exits non-zero on any failure.
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
cc=${KDRT_MINGW_CC:-x86_64-w64-mingw32-gcc-posix}
cxx=${KDRT_MINGW_CXX:-x86_64-w64-mingw32-g++-posix}
wine=${KDRT_WINE:-/usr/lib/wine/wine64}
wineserver=${KDRT_WINESERVER:-/usr/lib/wine/wineserver}
mingw_nm=${KDRT_MINGW_NM:-x86_64-w64-mingw32-nm}
clang=${KDRT_CLANG:-clang}
host_cc=${CC:-cc}
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

# compile OUTPUT COMPILER FLAGS... : OUTPUT in $work, in the background, two at a time (the
# machine's two cores); a failure leaves OUTPUT.failed.
compiles=()
compile() {
    local output=$1 pid running
    shift
    echo "+ $* -o $output"
    ( cd "$work" && "$@" -o "$output" >"$output.build.log" 2>&1 ) || {
        cat "$work/$output.build.log" >&2
        touch "$work/$output.failed"
    } &
    compiles+=($!)
    while (( $(jobs -rp | wc -l) >= 2 )); do wait -n || true; done # each leaves its .failed
}

compile smoke_c99.exe "$cc" -std=c99 "${release[@]}" "${warnings[@]}" "${strict[@]}" "${include[@]}" \
    "$root/tests/smoke_c99.c" -static
compile smoke_stats.exe "$cc" -std=c99 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/tests/smoke_stats.c" -static
compile smoke_cpp11.exe "$cxx" -std=c++11 "${release[@]}" "${warnings[@]}" "${strict[@]}" "${include[@]}" \
    "$root/tests/smoke_cpp11.cpp" -static
compile minimal.exe "$cc" -std=c99 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/examples/minimal.c" -static
compile engine.exe "$cxx" -std=c++17 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/examples/engine.cpp" -static -pthread
compile instances.exe "$cxx" -std=c++17 "${release[@]}" "${warnings[@]}" "${include[@]}" \
    "$root/examples/instances.cpp" -static
# The stored answers (answers.c, answers.txt: every kernel this CPU has, bit for bit) and the
# trees saved on Linux (answers.kdrt, loaded and checked by the same run), built as native.sh's
# strict C99 build is.
compile answers.exe "$cc" -std=c99 -O2 "${warnings[@]}" "${include[@]}" "$root/tests/platforms/answers.c" -static
# kernel_report with kdrt's assertions on (no NDEBUG), at the strict warnings.
compile kernel_report.exe "$cc" -std=c99 -O2 "${warnings[@]}" "${strict[@]}" "${include[@]}" \
    "$root/tests/platforms/kernel_report.c" -static
# kdrt compiled by clang for MSVC's target, as clang-cl compiles it and in cl.exe's macro set
# (msvc.sh and cl_macros.c say what each stands for), each linked by mingw-w64 with
# kernel_report (C's MSVC ABI is mingw-w64's): the cpuid check and those builds' kernels at work
# under wine.
msvc=("$clang" --target=x86_64-pc-windows-msvc -fms-extensions -fms-compatibility
      -fms-compatibility-version=19.30 -isystem "$root/tests/platforms/msvc-libc")
printf '#define KDRT_IMPLEMENTATION\n#include "kdrt.h"\n' >"$work/clang_cl.c"
compile kdrt_clang_cl.obj "${msvc[@]}" -x c -std=c99 -O2 -DKDRT_TRAVERSAL_STATS "${warnings[@]}" \
    "${strict[@]}" "${include[@]}" -c clang_cl.c
compile kdrt_cl_macros.obj "${msvc[@]}" -U__clang__ -x c -std=c99 -O2 -DKDRT_TRAVERSAL_STATS "${warnings[@]}" "${strict[@]}" "${include[@]}" -c "$root/tests/platforms/cl_macros.c"
compile kernel_report_linked.o "$cc" -std=c99 -O2 -DKERNEL_REPORT_LINKED "${warnings[@]}" "${strict[@]}" \
    "${include[@]}" -c "$root/tests/platforms/kernel_report.c"
# clang for mingw-w64 (as llvm-mingw builds): the GCC path, __builtin_cpu_supports from the
# runtime library (here libgcc's, in mingw-w64 GCC's directory; linked by mingw-w64's ld).
compile kernel_report_clang_mingw.exe "$clang" --target=x86_64-w64-mingw32 -std=c99 -O2 \
    "${warnings[@]}" "${strict[@]}" "${include[@]}" "$root/tests/platforms/kernel_report.c" -static \
    -L"$(dirname "$("$cc" -print-libgcc-file-name)")"
# And natively, for the answers Linux gives.
compile kernel_report_native "$host_cc" -std=c99 -O2 "${warnings[@]}" "${strict[@]}" "${include[@]}" \
    "$root/tests/platforms/kernel_report.c" -lm
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
# The implementation must come from the MSVC objects alone.
if "$mingw_nm" "$work/kernel_report_linked.o" | grep -q ' T kdrt_tree_build$'; then
    echo "windows.sh: FAILED: kernel_report_linked.o has an implementation of its own" >&2
    exit 1
fi
# _fltused and __chkstk are the MSVC CRT's: _fltused is only referenced (to link the CRT's
# floating-point support); __chkstk probes the stack as libgcc's ___chkstk_ms does (on x64: rax
# bytes, rsp and the registers kept).
for build in clang_cl cl_macros; do
    echo "+ $cc kernel_report_linked.o kdrt_$build.obj -static -Wl,--defsym=_fltused=0 -Wl,--defsym=__chkstk=___chkstk_ms -Wl,-u,___chkstk_ms -o kernel_report_$build.exe"
    if ! (cd "$work" && "$cc" kernel_report_linked.o "kdrt_$build.obj" -static -Wl,--defsym=_fltused=0 \
        -Wl,--defsym=__chkstk=___chkstk_ms -Wl,-u,___chkstk_ms -o "kernel_report_$build.exe"); then
        echo "windows.sh: FAILED: kernel_report_$build.exe did not link" >&2
        exit 1
    fi
done
echo "built in $((SECONDS - start)) s"

wait # wineboot too
if [ "$(cat "$work/wineboot.status" 2>/dev/null)" != 0 ]; then
    cat "$work/wineboot.log" >&2
    echo "windows.sh: FAILED: wineboot could not make the prefix" >&2
    exit 1
fi
echo "wine prefix ready at $((SECONDS - start)) s"

failures=0
# run NAME EXPECTED... : runs NAME.exe under wine (answers.exe with answers.txt, answers.kdrt
# beside it, as its header comment says); it must exit 0 and its output (CRLF made LF) must hold
# each EXPECTED line (a grep -E pattern).
run() {
    local name=$1 status=0 pattern arguments=()
    shift
    if [ "$name" = answers ]; then arguments=(answers.txt); fi
    echo "+ $wine $name.exe ${arguments[*]}"
    (cd "$work" && "$wine" "$name.exe" "${arguments[@]}") >"$work/$name.out" 2>"$work/$name.err" || status=$?
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
cp "$root/tests/platforms/answers.txt" "$root/tests/platforms/answers.kdrt" "$work/"
saved_ok="640 rays, 0 differ from the file, 0 batch answers differ, 0 of 4 trees save to other bytes"
run answers "^answers: kernel $default_kernel, builder sah: 640 rays, 0 differ from the file, 0 batch answers differ$" \
    "^answers: kernel scalar, builder sah: 640 rays, 0 differ from the file, 0 batch answers differ$" \
    "^answers: saved trees copied, kernel $default_kernel: $saved_ok$" \
    "^answers: saved trees in place, kernel scalar: $saved_ok$" \
    "^[1-9][0-9]* passed, 0 failed$"
echo "+ kernel_report_native"
if ! (cd "$work" && ./kernel_report_native) >"$work/native.txt"; then
    echo "windows.sh: FAILED: the native kernel_report failed" >&2
    failures=$((failures + 1))
fi
sed 's/^/    /' "$work/native.txt"
answers=$(grep -m1 '^answers: ' "$work/native.txt" || echo "answers: none")
reports=(kernel_report kernel_report_clang_mingw kernel_report_clang_cl)
# cl_macros.c gives every function of the implementation AVX-512 (clang, unlike cl.exe, wants an
# intrinsic's target on its function), so its build runs only where the CPU has AVX-512.
if has avx512f; then
    reports+=(kernel_report_cl_macros)
else
    echo "kernel_report_cl_macros.exe: compiled and linked, not run: its every function has AVX-512 code, and this CPU has no AVX-512"
fi
for report in "${reports[@]}"; do
    run "$report" "^kernel default: $default_kernel " "^kernel KDRT_BUILD_AVX2_KERNEL: $avx2_kernel " \
        "^kernel KDRT_BUILD_SCALAR_KERNEL: scalar " "^$answers\$" "^kernel_report: all checks passed$"
done

echo "windows.sh: $((SECONDS - start)) s in all"
if [ "$failures" != 0 ]; then
    echo "windows.sh: FAILED: $failures checks" >&2
    exit 1
fi
echo "windows.sh: all passed"
