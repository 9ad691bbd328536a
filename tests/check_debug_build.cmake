# The implementation compiled as a debug build (-O0, where GCC's SIMD intrinsics are macros that
# expand in kdrt's code) is free of warnings at the strict levels too, as C99 and as C++11.
#   cmake -DC_COMPILER=... -DCXX_COMPILER=... -DINCLUDE=... -DWORK=... -P check_debug_build.cmake
file(MAKE_DIRECTORY "${WORK}")
file(WRITE "${WORK}/implementation.c" "#define KDRT_IMPLEMENTATION\n#include \"kdrt.h\"\n")
set(strict -O0 -Wall -Wextra -pedantic -Wconversion -Wsign-conversion -Wshadow -Werror)
foreach(language c c++)
  if(language STREQUAL "c")
    set(command "${C_COMPILER}" -std=c99)
  else()
    set(command "${CXX_COMPILER}" -std=c++11 -x c++)
  endif()
  execute_process(COMMAND ${command} ${strict} -I "${INCLUDE}" -c "${WORK}/implementation.c"
                          -o "${WORK}/implementation-${language}.o"
                  RESULT_VARIABLE status ERROR_VARIABLE err)
  if(NOT status EQUAL 0)
    message(FATAL_ERROR "the implementation's -O0 build as ${language} failed:\n${err}")
  endif()
endforeach()
