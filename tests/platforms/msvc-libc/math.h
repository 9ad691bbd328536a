/* Stand-in for the UCRT's math.h (tests/platforms/msvc.sh): exactly what kdrt.h uses, declared as
   the UCRT declares it: INFINITY, sqrt, fma, fabs. */
#ifndef KDRT_MSVC_LIBC_MATH_H
#define KDRT_MSVC_LIBC_MATH_H
#ifdef __cplusplus
extern "C" {
#endif
#define _HUGE_ENUF 1e+300 /* the UCRT's INFINITY: a product that overflows */
#define INFINITY ((float)(_HUGE_ENUF * _HUGE_ENUF))
double __cdecl sqrt(double x);
double __cdecl fma(double x, double y, double z);
double __cdecl fabs(double x);
#ifdef __cplusplus
}
#endif
#endif
