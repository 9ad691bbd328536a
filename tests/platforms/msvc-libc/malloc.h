/* Stand-in for the UCRT's malloc.h (tests/platforms/msvc.sh): not kdrt.h's, clang's mm_malloc.h's
   (included by xmmintrin.h in a hosted build): _aligned_malloc, _aligned_free. */
#ifndef KDRT_MSVC_LIBC_MALLOC_H
#define KDRT_MSVC_LIBC_MALLOC_H
#include <stddef.h>
#ifdef __cplusplus
extern "C" {
#endif
void *__cdecl _aligned_malloc(size_t size, size_t alignment);
void __cdecl _aligned_free(void *block);
#ifdef __cplusplus
}
#endif
#endif
