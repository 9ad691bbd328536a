# kdrt-bench -o OUT never loses the OUT of an earlier run: rows go to OUT.partial, flushed and
# checked one by one, which is renamed over OUT only when the run ends with a row written and
# every write checked (bench/README.md). BENCH, MESH (a good mesh) and DIR (a scratch folder).
include("${CMAKE_CURRENT_LIST_DIR}/bench_csv_rows.cmake")
include("${CMAKE_CURRENT_LIST_DIR}/expect_failure.cmake")
set(out "${DIR}/bench_output.csv")
set(partial "${out}.partial")
set(old "the old results\n")

# Runs kdrt-bench with ARGN and -o OUT; it must fail, saying EXPECT on stderr, and leave OUT as
# it was.
function(bench_fails expect)
  expect_failure("${expect}" /dev/null ${ARGN} -o "${out}")
  file(READ "${out}" text)
  if(NOT text STREQUAL old)
    message(FATAL_ERROR "${out} was changed")
  endif()
endfunction()

# Every input fails, so no row is written: OUT is left as it was, and no partial file.
file(REMOVE "${partial}")
file(WRITE "${out}" "${old}")
bench_fails("no row was written; '[^']*bench_output.csv' is as it was"
            "${BENCH}" --sweep --size 8x8 --leaf-sizes 1 /no/such/mesh.obj)
if(EXISTS "${partial}")
  message(FATAL_ERROR "${partial} is left")
endif()

# The disk fills after a few rows (ulimit -f 1 in bash: 1 KiB, the header and about nine rows):
# OUT is left as it was, and OUT.partial holds the whole rows written before.
bench_fails("cannot write '[^']*partial': File too large; the [1-9][0-9]* row\\(s\\) so far are in '[^']*bench_output.csv.partial', and '[^']*bench_output.csv' is as it was"
            bash -c "ulimit -f 1 && trap '' XFSZ && exec \"$@\"" bash
            "${BENCH}" --sweep --size 8x8 --leaf-sizes 1,2,3,4,6,8 --repeat 4 "${MESH}")
check_whole_rows("${partial}" 1)

# A read-only OUT is refused before any work, root or not.
file(REMOVE "${partial}")
file(CHMOD "${out}" PERMISSIONS OWNER_READ GROUP_READ WORLD_READ)
bench_fails("cannot write '[^']*bench_output.csv': it is read-only" "${BENCH}" --sweep --size 8x8 --leaf-sizes 1 "${MESH}")
file(CHMOD "${out}" PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ)
if(EXISTS "${partial}")
  message(FATAL_ERROR "${partial} is left")
endif()

# A run that ends well replaces OUT through the partial file, which is then gone.
execute_process(COMMAND "${BENCH}" --sweep --size 8x8 --leaf-sizes 1,2 "${MESH}" -o "${out}" RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "a good run exited ${result}")
endif()
check_whole_rows("${out}" 2)
if(EXISTS "${partial}")
  message(FATAL_ERROR "${partial} is left")
endif()
message(STATUS "OUT kept on no row, a full disk and read-only; replaced by a good run")
