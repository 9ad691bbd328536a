# kdrt-bench -o OUT killed mid-run (CMake kills it with SIGKILL when TIMEOUT runs out, a signal
# no program can catch) leaves OUT as it was and its rows so far in OUT.partial, every line
# whole: the header, then complete rows, each flushed as it was written.
include("${CMAKE_CURRENT_LIST_DIR}/bench_csv_rows.cmake")
file(REMOVE "${OUT}.partial")
file(WRITE "${OUT}" "the old results\n")
execute_process(
  COMMAND "${BENCH}" --sweep --size 64x64 --leaf-sizes 1,2,4 --repeat 1024 --reference-rays 16 -o "${OUT}"
  TIMEOUT 4
  RESULT_VARIABLE result)
if(result EQUAL 0)
  message(FATAL_ERROR "kdrt-bench finished 1024 repetitions of every frame in 4 s: the test did not interrupt it")
endif()
file(READ "${OUT}" text)
if(NOT text STREQUAL "the old results\n")
  message(FATAL_ERROR "${OUT} was changed by the killed run")
endif()
check_whole_rows("${OUT}.partial" 1)
message(STATUS "killed after ${ROWS} rows, every row whole in ${OUT}.partial, ${OUT} as it was")
