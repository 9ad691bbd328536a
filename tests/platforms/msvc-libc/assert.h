/* Stand-in for the UCRT's assert.h (tests/platforms/msvc.sh): assert, as the UCRT defines it. */
#include <stddef.h> /* wchar_t */
#undef assert
#ifdef NDEBUG
#define assert(expression) ((void)0)
#else
#ifdef __cplusplus
extern "C"
#endif
    void __cdecl _wassert(const wchar_t *message, const wchar_t *file, unsigned line);
#define KDRT_MSVC_LIBC_WIDE_(s) L##s
#define KDRT_MSVC_LIBC_WIDE(s) KDRT_MSVC_LIBC_WIDE_(s)
#define assert(expression)                                                                         \
    (void)((!!(expression)) ||                                                                     \
           (_wassert(KDRT_MSVC_LIBC_WIDE(#expression), KDRT_MSVC_LIBC_WIDE(__FILE__),              \
                     (unsigned)(__LINE__)),                                                        \
            0))
#endif
