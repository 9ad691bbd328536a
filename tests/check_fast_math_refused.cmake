# The implementation compiled with -ffast-math must stop with kdrt's #error, which names the flag;
# the header included without the implementation must compile under it. So must the
# implementation compiled for i386's x87 arithmetic, where the compiler can build for i386.
#   cmake -DCOMPILER=... -DINCLUDE=... -DWORK=... -P check_fast_math_refused.cmake
file(MAKE_DIRECTORY "${WORK}")
file(WRITE "${WORK}/implementation.c" "#define KDRT_IMPLEMENTATION\n#include \"kdrt.h\"\n")
file(WRITE "${WORK}/user.c" "#include \"kdrt.h\"\nint user(void) { return KDRT_MAX_DEPTH; }\n")
include("${CMAKE_CURRENT_LIST_DIR}/expect_failure.cmake")
foreach(flag -ffast-math -ffinite-math-only)
  message(STATUS "the implementation under ${flag}")
  expect_failure("kdrt: compile the file that defines KDRT_IMPLEMENTATION without -ffast-math"
                 "${WORK}/compiler-output.txt" "${COMPILER}" ${flag} -std=c99 -I "${INCLUDE}" -c
                 "${WORK}/implementation.c" -o "${WORK}/implementation.o")
endforeach()
execute_process(COMMAND "${COMPILER}" -ffast-math -std=c99 -I "${INCLUDE}" -c "${WORK}/user.c" -o "${WORK}/user.o"
                RESULT_VARIABLE status ERROR_VARIABLE err)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "the header alone did not compile under -ffast-math:\n${err}")
endif()

# x87: only where this compiler has i386's libraries (gcc-multilib) and builds with SSE2 there.
execute_process(COMMAND "${COMPILER}" -m32 -msse2 -mfpmath=sse -std=c99 -I "${INCLUDE}" -c
                "${WORK}/implementation.c" -o "${WORK}/implementation-sse2.o"
                RESULT_VARIABLE status ERROR_VARIABLE err)
if(status EQUAL 0)
  message(STATUS "the implementation under -m32 -mfpmath=387")
  expect_failure("kdrt: compile the file that defines KDRT_IMPLEMENTATION with SSE2 arithmetic"
                 "${WORK}/compiler-output.txt" "${COMPILER}" -m32 -mfpmath=387 -std=c99 -I "${INCLUDE}"
                 -c "${WORK}/implementation.c" -o "${WORK}/implementation-x87.o")
else()
  message(STATUS "no i386 build with SSE2 here (gcc-multilib missing?): the x87 refusal is not checked")
endif()
