/* Stand-in for the UCRT's stdlib.h (tests/platforms/msvc.sh): exactly what kdrt.h uses: malloc,
   free, qsort. */
#ifndef KDRT_MSVC_LIBC_STDLIB_H
#define KDRT_MSVC_LIBC_STDLIB_H
#include <stddef.h>
#ifdef __cplusplus
extern "C" {
#endif
void *__cdecl malloc(size_t size);
void __cdecl free(void *block);
void __cdecl qsort(void *base, size_t count, size_t size,
                   int(__cdecl *compare)(const void *, const void *));
#ifdef __cplusplus
}
#endif
#endif
