# kdrt-bench's first run on the octahedron, as a new user makes it: with no option, kdrt's default
# tree (the SAH builder at the default quality and costs, leaf size 4) and, when this kdrt-bench
# was built with Embree, Embree's row beside it; a progress line on standard error before each
# build; --quiet without them; and --sweep, the original's leaf-size run: the median builder at
# leaf sizes 0, 1, 2, 3, 4, 6 and 8 (the first at or above the mesh's 8 triangles), no
# Embree. BENCH, MESH (the octahedron) and DIR (a scratch folder).
include("${CMAKE_CURRENT_LIST_DIR}/bench_csv_rows.cmake")
set(out "${DIR}/bench_defaults.csv")
set(small --size 16x16 --reference-rays 64)

# Whether this kdrt-bench has Embree, asked apart from the run under test.
execute_process(COMMAND "${BENCH}" --compare embree ${small} "${MESH}" -o "${out}"
                RESULT_VARIABLE result OUTPUT_QUIET ERROR_VARIABLE err)
set(embree ON)
if(err MATCHES "built without Embree")
  set(embree OFF)
endif()

# The default run.
file(REMOVE "${out}")
execute_process(COMMAND "${BENCH}" ${small} "${MESH}" -o "${out}" RESULT_VARIABLE result ERROR_VARIABLE err)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "the default run exited ${result}: ${err}")
endif()
file(READ "${out}" text)
string(REPLACE ";" "|" text "${text}")
string(STRIP "${text}" text)
string(REPLACE "\n" ";" lines "${text}")
list(POP_FRONT lines header)
list(LENGTH lines n)
set(sah_row "^OCTAHEDRON\\|4\\|[0-9]+\\|sah\\|10\\|.*\\|0\\|64\\|watertight\\|[0-9.]+\\|30:20:0\\.1\\|1\\|default\\|plain\\|root\\|single\\|(scalar|avx2|avx512)$")
set(embree_row "^OCTAHEDRON\\|-1\\|[0-9]+\\|embree\\|10\\|.*\\|0\\|64\\|\\|\\|\\|1\\|medium\\|\\|\\|single\\|$")
if(embree)
  set(expected 2)
else()
  set(expected 1)
endif()
if(NOT n EQUAL expected)
  message(FATAL_ERROR "the default run (Embree ${embree}): expected ${expected} row(s), got ${n}: ${lines}")
endif()
list(GET lines 0 row)
if(NOT row MATCHES "${sah_row}")
  message(FATAL_ERROR "the default run's first row is not the SAH tree at leaf size 4: ${row}")
endif()
set(so_far "( \\([0-9]+ s so far\\))?\n")  # after the first second of a slow machine
set(progress "kdrt-bench: \\[1/${expected}\\] OCTAHEDRON: sah leaf 4: building and tracing 16x16 primary rays${so_far}")
if(embree)
  list(GET lines 1 row)
  if(NOT row MATCHES "${embree_row}")
    message(FATAL_ERROR "the default run's second row is not Embree's: ${row}")
  endif()
  string(APPEND progress "kdrt-bench: \\[2/2\\] OCTAHEDRON: embree medium: building and tracing 16x16 primary rays${so_far}")
elseif(NOT err MATCHES "kdrt-bench: built without Embree: kdrt's rows only")
  message(FATAL_ERROR "a kdrt-bench without Embree does not say so: ${err}")
endif()
if(NOT err MATCHES "${progress}")
  message(FATAL_ERROR "the progress lines on standard error are not '${progress}': ${err}")
endif()

# --quiet: the same rows, no progress.
execute_process(COMMAND "${BENCH}" --quiet ${small} "${MESH}" -o "${out}" RESULT_VARIABLE result ERROR_VARIABLE err)
if(NOT result EQUAL 0 OR NOT err STREQUAL "")
  message(FATAL_ERROR "--quiet exited ${result} and said: ${err}")
endif()

# --sweep: the rows the original benchmark wrote, and a progress line for each.
execute_process(COMMAND "${BENCH}" --sweep ${small} "${MESH}" -o "${out}" RESULT_VARIABLE result ERROR_VARIABLE err)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "--sweep exited ${result}: ${err}")
endif()
check_whole_rows("${out}" 7)  # median rows only, Embree's none
if(NOT ROWS EQUAL 7)
  message(FATAL_ERROR "--sweep: expected 7 rows, got ${ROWS}")
endif()
file(STRINGS "${out}" lines)
set(i 0)
foreach(leaf 0 1 2 3 4 6 8)
  math(EXPR i "${i} + 1")
  list(GET lines ${i} row)
  if(NOT row MATCHES "^OCTAHEDRON;${leaf};[0-9]+;median;10;")
    message(FATAL_ERROR "--sweep: row ${i} is not the median tree at leaf size ${leaf}: ${row}")
  endif()
  if(NOT err MATCHES "kdrt-bench: \\[${i}/7\\] OCTAHEDRON: median leaf ${leaf}: building and tracing")
    message(FATAL_ERROR "--sweep: no progress line for leaf size ${leaf}: ${err}")
  endif()
endforeach()
message(STATUS "default run: SAH leaf 4 (Embree ${embree}); --sweep: 7 median rows; progress on stderr")
