/* Stand-in for the UCRT's setjmp.h (tests/platforms/msvc.sh): not kdrt.h's, clang's intrin.h's,
   which declares _setjmp(jmp_buf): jmp_buf, as the UCRT defines it on x64. */
#ifndef KDRT_MSVC_LIBC_SETJMP_H
#define KDRT_MSVC_LIBC_SETJMP_H
typedef struct __declspec(align(16)) _SETJMP_FLOAT128 {
    unsigned __int64 Part[2];
} SETJMP_FLOAT128;
#define _JBLEN 16
typedef SETJMP_FLOAT128 _JBTYPE;
typedef _JBTYPE jmp_buf[_JBLEN];
#endif
