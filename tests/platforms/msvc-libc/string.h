/* Stand-in for the UCRT's string.h (tests/platforms/msvc.sh): exactly what kdrt.h uses: memcpy,
   memset. */
#ifndef KDRT_MSVC_LIBC_STRING_H
#define KDRT_MSVC_LIBC_STRING_H
#include <stddef.h>
#ifdef __cplusplus
extern "C" {
#endif
void *__cdecl memcpy(void *destination, const void *source, size_t size);
void *__cdecl memset(void *destination, int value, size_t size);
#ifdef __cplusplus
}
#endif
#endif
