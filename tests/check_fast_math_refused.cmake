# The implementation compiled with -ffast-math must stop with kdrt's #error, which names the flag;
# the header included without the implementation must compile under it.
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
