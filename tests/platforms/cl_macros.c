/* kdrt's implementation in cl.exe's macro set, compiled by clang for MSVC's target with
   -U__clang__ (tests/platforms/msvc.sh, windows.sh). MSVC's immintrin.h declares every
   intrinsic, clang's only those the flags enable: the rest are named here. And clang, unlike
   cl.exe, refuses an intrinsic in a function without its target: kdrt's functions get
   "avx2,avx512f" from the pragma, without a -m flag, so that __AVX2__ and __FMA__ stay
   undefined as under cl.exe's default /arch. */
#include <immintrin.h>
#include <smmintrin.h>
#include <avxintrin.h>
#include <avx2intrin.h>
#include <fmaintrin.h>
#include <avx512fintrin.h>
#pragma clang attribute push(__attribute__((target("avx2,avx512f"))), apply_to = function)
/* kdrt.h turns contraction off for cl.exe with MSVC's #pragma fp_contract(off), which clang
   does not know (every function here has FMA): the same in clang's words, and the unknown
   pragma not named. */
#pragma clang fp contract(off)
#pragma clang diagnostic ignored "-Wunknown-pragmas"
#define KDRT_IMPLEMENTATION
#include "kdrt.h"
#pragma clang attribute pop
