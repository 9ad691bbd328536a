#!/usr/bin/env bash
# kdrt's implementation compiled for MSVC's target with this machine's tools (clang, no Windows
# SDK), and its object code checked: the AVX2 and AVX-512 kernels are in it, chosen by cpuid and
# xgetbv, with no symbol a plain MSVC link cannot resolve.
#   tests/platforms/msvc.sh
# 1. As clang-cl compiles it (x86_64-pc-windows-msvc, -fms-extensions -fms-compatibility; C99
#    and C++14, MSVC's oldest C++ mode; -O2 and -O0), with -Wall -Wextra -pedantic and the smoke
#    tests' -Wconversion -Wsign-conversion -Wshadow as errors (/W4 and more). Then llvm-objdump
#    must find ymm and zmm instructions, only in the kernels' own functions (_avx2, _avx512),
#    and cpuid and xgetbv; llvm-nm must find no undefined symbol but the C runtime's: none of
#    compiler-rt's (__cpu_model, __cpu_indicator_init: __builtin_cpu_supports).
# 2. In cl.exe's macro set: _MSC_VER, and neither __clang__ (-U__clang__; clang's own headers
#    never test it) nor __GNUC__ (never defined for this target). kdrt.h then takes its cl.exe
#    paths: no target attributes, _BitScanForward, the cpuid check. The wrapper, cl_macros.c,
#    names clang's AVX, AVX2 and AVX-512 headers, as MSVC's immintrin.h declares every
#    intrinsic, and gives kdrt's functions the "avx2,avx512f" target with #pragma clang
#    attribute (clang, unlike cl.exe, refuses intrinsics outside their target); no -m flag, so
#    that __AVX2__ and __FMA__ stay undefined as under cl.exe's default /arch. Its preprocessed kdrt.h code must hold no
#    __attribute__, __asm__ or __builtin_ of its own (clang's intrinsic macros expand to
#    __builtin_ia32_*, which MSVC's are functions for), and its syntax tree (clang -ast-dump) no
#    GNU vector operation in kdrt.h's code: no operator but = and , on a vector value (a + b,
#    a < b, ~a, a += b), no element v[i], no cast of one vector type to another, explicit or
#    implicit; MSVC's __m256 and __m512 are unions, with none of them.
# What this proves: kdrt.h's MSVC paths are C99 and C++ that clang accepts in MSVC mode, warning
# free, and that clang-cl's object code holds both kernels and needs no runtime library. What it
# does not: that cl.exe itself accepts them (its parser, its /W4 warnings, its intrinsic headers'
# declarations) or how cl.exe's code runs; only an MSVC build can tell.
# The C library's headers (the UCRT's) are absent here: tests/platforms/msvc-libc/ declares what
# kdrt.h and clang's intrinsic headers use from them; clang's resource headers give stddef.h,
# stdint.h and the intrinsics. Uses clang, llvm-objdump and llvm-nm (KDRT_CLANG, KDRT_OBJDUMP,
# KDRT_NM override them). Exits non-zero on any failure.
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
clang=${KDRT_CLANG:-clang}
objdump=${KDRT_OBJDUMP:-llvm-objdump}
nm=${KDRT_NM:-llvm-nm}
for tool in "$clang" "$objdump" "$nm"; do
    command -v "$tool" >/dev/null || { echo "msvc.sh: FAILED: $tool not found" >&2; exit 1; }
done
start=$SECONDS
work=$(mktemp -d "${TMPDIR:-/tmp}/kdrt-msvc.XXXXXX")
trap 'rm -rf "$work"' EXIT

target=(--target=x86_64-pc-windows-msvc -fms-extensions -fms-compatibility -fms-compatibility-version=19.30)
warnings=(-Wall -Wextra -pedantic -Wconversion -Wsign-conversion -Wshadow -Werror)
include=(-isystem "$root/tests/platforms/msvc-libc" -I"$root/include")
# What an MSVC program's link resolves from the CRT (the UCRT, vcruntime) for kdrt: its libc
# calls, and what clang emits for MSVC itself (_fltused: floats in use; __chkstk: frames of more
# than a page, the batches'; _wassert: assert). Nothing else may be undefined.
crt_symbols=" _fltused __chkstk _wassert malloc free qsort memcmp memcpy memmove memset sqrt fma fabs "

printf '#define KDRT_IMPLEMENTATION\n#include "kdrt.h"\n' >"$work/clang_cl.c"

failures=0
fail() {
    echo "msvc.sh: FAILED: $*" >&2
    failures=$((failures + 1))
}

# compile NAME SOURCE FLAGS...: NAME.obj, in the background, two at a time (the machine's two
# cores); the command printed; a failure leaves NAME.failed.
compiles=()
compile() {
    local name=$1 source=$2 pid running
    shift 2
    echo "+ $clang ${target[*]} $* ${warnings[*]} -isystem tests/platforms/msvc-libc -Iinclude -c $(basename "$source") -o $name.obj"
    "$clang" "${target[@]}" "$@" "${warnings[@]}" "${include[@]}" -c "$source" -o "$work/$name.obj" \
        2>"$work/$name.log" || touch "$work/$name.failed" &
    compiles+=($!)
    while (( $(jobs -rp | wc -l) >= 2 )); do wait -n || true; done # each leaves its .failed
}

# compiled NAME: whether NAME.obj compiled (its errors printed, and counted, if not).
compiled() {
    if [ -e "$work/$1.failed" ]; then
        cat "$work/$1.log" >&2
        fail "$1 did not compile"
        return 1
    fi
}

# check_object NAME: the kernels' instructions where they belong, cpuid and xgetbv, and nothing
# undefined but the CRT's.
check_object() {
    local name=$1 obj=$work/$1.obj symbol misplaced
    "$objdump" -d --no-show-raw-insn "$obj" >"$work/$name.s"
    # each function's count of ymm and zmm operands, by name (C++'s ?name@@... mangling dropped)
    awk '/^[0-9a-f]+ <.*>:$/ { f = substr($2, 2, length($2) - 3); if (f ~ /^\?/) f = substr(f, 2, index(f, "@") - 2); next }
         /%?ymm[0-9]/ { y[f]++ } /%?zmm[0-9]/ { z[f]++ }
         END { for (f in y) print "ymm", f, y[f]; for (f in z) print "zmm", f, z[f] }' \
        "$work/$name.s" | sort >"$work/$name.vectors"
    grep -q '^ymm ' "$work/$name.vectors" || fail "$name: no ymm instruction (no AVX2 kernel)"
    grep -q '^zmm ' "$work/$name.vectors" || fail "$name: no zmm instruction (no AVX-512 kernel)"
    misplaced=$(awk '($1 == "ymm" && $2 !~ /_avx(2|512)$/) || ($1 == "zmm" && $2 !~ /_avx512$/)' "$work/$name.vectors")
    [ -z "$misplaced" ] || fail "$name: vector instructions outside the kernels' functions (code a CPU without AVX2 would run): $misplaced"
    grep -Eq '\scpuid$' "$work/$name.s" || fail "$name: no cpuid instruction"
    grep -Eq '\sxgetbv$' "$work/$name.s" || fail "$name: no xgetbv instruction"
    "$nm" --undefined-only "$obj" | awk '{ print $NF }' >"$work/$name.undefined"
    while read -r symbol; do
        case "$crt_symbols" in *" $symbol "*) ;; *) fail "$name: undefined symbol $symbol, not the CRT's" ;; esac
    done <"$work/$name.undefined"
    echo "  $name.obj: vector code in $(awk '{print $2}' "$work/$name.vectors" | sort -u | tr '\n' ' '); cpuid and xgetbv; undefined: $(tr '\n' ' ' <"$work/$name.undefined")"
}

clang_cl_variants=("c99 -x c -std=c99 -O2" "cpp14 -x c++ -std=c++14 -O2" "c99_O0 -x c -std=c99 -O0"
                   "cpp14_O0 -x c++ -std=c++14 -O0")
cl_variants=("c99 -x c -std=c99 -O2" "cpp14 -x c++ -std=c++14 -O2")
echo "compiling: 1. as clang-cl compiles; 2. in cl.exe's macro set"
for variant in "${clang_cl_variants[@]}"; do
    read -r name flags <<<"$variant"
    # shellcheck disable=SC2086
    compile "clang_cl_$name" "$work/clang_cl.c" $flags
done
for variant in "${cl_variants[@]}"; do
    read -r name flags <<<"$variant"
    # shellcheck disable=SC2086
    compile "cl_macros_$name" "$root/tests/platforms/cl_macros.c" -U__clang__ $flags
done
for pid in "${compiles[@]}"; do wait "$pid" || true; done # each leaves its .failed

echo "1. clang-cl's objects"
for variant in "${clang_cl_variants[@]}"; do
    read -r name flags <<<"$variant"
    if compiled "clang_cl_$name"; then check_object "clang_cl_$name"; fi
done

echo "2. cl.exe's macro set"
# The macros as cl.exe's headers and kdrt.h see them.
echo "+ $clang ${target[*]} -U__clang__ -dM -E"
macros=$("$clang" "${target[@]}" -U__clang__ -dM -E -x c /dev/null)
for macro in _MSC_VER _M_X64 _WIN64; do
    grep -q "^#define $macro " <<<"$macros" || fail "cl.exe's macro set: $macro undefined"
done
for macro in __clang__ __GNUC__ __AVX2__ __FMA__ __AVX512F__; do
    if grep -q "^#define $macro " <<<"$macros"; then fail "cl.exe's macro set: $macro defined"; fi
done
for variant in "${cl_variants[@]}"; do
    read -r name flags <<<"$variant"
    compiled "cl_macros_$name" || continue
    # kdrt.h's own lines after preprocessing: no GNU construct of its own
    # shellcheck disable=SC2086
    "$clang" "${target[@]}" -U__clang__ $flags "${include[@]}" -E "$root/tests/platforms/cl_macros.c" |
        awk '/^# [0-9]+ "/ { file = $3; next } file ~ /\/kdrt\.h"$/' >"$work/cl_macros_$name.i"
    grep -q 'kdrt__cpu_vector_level' "$work/cl_macros_$name.i" || fail "cl_macros_$name: the cpuid check is not compiled"
    grep -q '_BitScanForward' "$work/cl_macros_$name.i" || fail "cl_macros_$name: kdrt__ctz is not _BitScanForward"
    gnu=$(grep -Eo '__attribute__|__asm__|__asm\b|__builtin_[A-Za-z0-9_]*' "$work/cl_macros_$name.i" |
        grep -v '^__builtin_ia32_' | sort | uniq -c || true)
    if [ -z "$gnu" ]; then
        echo "  cl_macros_$name.obj compiled; kdrt.h's code holds no __attribute__, __asm__ or __builtin_ of its own"
    else
        fail "cl_macros_$name: GNU constructs in kdrt.h's code in cl.exe's macro set: $gnu"
    fi
done

# GNU vector operations in kdrt.h's code, from clang's syntax tree of the C compile.
cat >"$work/vector_operations.awk" <<'EOF'
# Operators applied to vector values (GNU vector extensions; MSVC's __m256 and __m512 are unions
# and have none) in kdrt.h's code, from clang's -ast-dump: each node's file is its range's first
# location's, printed only where it changes.
{
    line = $0
    first = ""
    if (match(line, /<[^>]*>/)) {
        range = substr(line, RSTART + 1, RLENGTH - 2)
        if (match(range, /^[^ ,:<]+\.[a-z]+:[0-9]+:[0-9]+/)) {
            first = substr(range, 1, RLENGTH); sub(/:[0-9]+:[0-9]+$/, "", first)
        }
    }
    node_file = first != "" ? first : last
    # the last file named on the line is the one later lines' locations are in
    rest = line
    while (match(rest, /[^ ,:<>]+\.[a-z]+:[0-9]+:[0-9]+/)) {
        f = substr(rest, RSTART, RLENGTH); sub(/:[0-9]+:[0-9]+$/, "", f); last = f
        rest = substr(rest, RSTART + RLENGTH)
    }
    subscript = previous_subscript; previous_subscript = 0
    if (node_file !~ /\/kdrt\.h$/) next
    # an element of a vector (v[i]), or an operator whose value is a vector, other than = and ,
    # (which structs have too): its type is the first quoted one on the line
    # (v[i] of an lvalue is marked vectorcomponent; of an rvalue, its base below it is a vector)
    if (line ~ /vectorcomponent/) { print node_file ": " line; next }
    if (line ~ /-ArraySubscriptExpr /) { previous_subscript = 1; next }
    if (!match(line, /'[^']*'(:'[^']*')?/)) next
    type = substr(line, RSTART, RLENGTH)
    vector = type ~ /__vector_size__/ && type !~ /[*\]]'?$/
    if (subscript && vector) { print node_file ": a vector's element: " line; next }
    if (!vector) next
    # a vector cast to another vector's type (MSVC has the _mm*_cast* intrinsics for that)
    if (line ~ /CastExpr / && line ~ /<BitCast>/) { print node_file ": a cast: " line; next }
    if (line !~ /-(BinaryOperator|CompoundAssignOperator|UnaryOperator) /) next
    if (line ~ /-BinaryOperator / && line ~ /'(=|,)'( |$)/) next
    if (line ~ /-UnaryOperator / && line ~ /prefix '\*'/) next
    print node_file ": " line
}
EOF
echo "+ $clang ${target[*]} -U__clang__ -x c -std=c99 -fsyntax-only -Xclang -ast-dump cl_macros.c | awk -f vector_operations.awk"
if "$clang" "${target[@]}" -U__clang__ -x c -std=c99 "${include[@]}" -fsyntax-only -Xclang -ast-dump \
    -fno-color-diagnostics "$root/tests/platforms/cl_macros.c" >"$work/cl_macros.ast"; then
    awk -f "$work/vector_operations.awk" "$work/cl_macros.ast" >"$work/vector_operations.txt"
    grep -q 'kdrt__batch_avx512' "$work/cl_macros.ast" || fail "the syntax tree holds no AVX-512 kernel"
    if [ -s "$work/vector_operations.txt" ]; then
        fail "GNU vector operations in kdrt.h, which cl.exe does not have: $(cat "$work/vector_operations.txt")"
    else
        echo "  kdrt.h's code: no operator, element access or cast on a vector value"
    fi
else
    fail "clang -ast-dump of cl_macros.c"
fi

echo "msvc.sh: $((SECONDS - start)) s"
if [ "$failures" != 0 ]; then
    echo "msvc.sh: FAILED: $failures checks" >&2
    exit 1
fi
echo "msvc.sh: all passed"
