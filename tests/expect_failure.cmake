# expect_failure(EXPECT STDOUT COMMAND...): runs COMMAND with its standard output to the file
# STDOUT and requires it to fail cleanly: a non-zero exit status and standard error matching
# EXPECT. Included by the scripts that check a program's failures (check_fails.cmake,
# check_bench_output.cmake, check_fast_math_refused.cmake).
function(expect_failure expect stdout)
  execute_process(COMMAND ${ARGN} OUTPUT_FILE "${stdout}" ERROR_VARIABLE err RESULT_VARIABLE result)
  message(STATUS "exit status ${result}, standard error: ${err}")
  if(result EQUAL 0)
    message(FATAL_ERROR "it exited 0")
  endif()
  if(NOT err MATCHES "${expect}")
    message(FATAL_ERROR "standard error does not match '${expect}'")
  endif()
endfunction()
