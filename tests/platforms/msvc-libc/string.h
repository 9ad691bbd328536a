/* Stand-in for the UCRT's string.h (tests/platforms/msvc.sh): exactly what kdrt.h uses: memcmp,
   memcpy, memmove, memset. */
#ifndef KDRT_MSVC_LIBC_STRING_H
#define KDRT_MSVC_LIBC_STRING_H
#include <stddef.h>
#ifdef __cplusplus
extern "C" {
#endif
int __cdecl memcmp(const void *a, const void *b, size_t size);
void *__cdecl memcpy(void *destination, const void *source, size_t size);
void *__cdecl memmove(void *destination, const void *source, size_t size);
void *__cdecl memset(void *destination, int value, size_t size);
#ifdef __cplusplus
}
#endif
#endif
