# A first configure of the repository says nothing alarming: Debian's Imath package reports a
# library of python3-imath missing (Imath::PyImath_Python3_11), which kdrt never uses, and
# examples/render/CMakeLists.txt keeps that message quiet. Configures SOURCE afresh in BINARY.
file(REMOVE_RECURSE "${BINARY}")
execute_process(COMMAND ${CMAKE_COMMAND} -S "${SOURCE}" -B "${BINARY}" -DKDRT_BUILD_TESTS=OFF
                RESULT_VARIABLE status OUTPUT_VARIABLE out ERROR_VARIABLE err)
file(REMOVE_RECURSE "${BINARY}")
if(NOT status EQUAL 0)
  message(FATAL_ERROR "configure failed (${status}):\n${out}\n${err}")
endif()
foreach(alarm "PyImath" "does not exist" "CMake Warning")
  string(FIND "${out}${err}" "${alarm}" at)
  if(NOT at EQUAL -1)
    message(FATAL_ERROR "the configure output says '${alarm}':\n${out}\n${err}")
  endif()
endforeach()
message(STATUS "configure is quiet")
