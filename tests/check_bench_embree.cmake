# kdrt-bench --compare embree on the octahedron: an Embree row beside kdrt's, with no mismatch
# against the oracle. Reported as skipped when this kdrt-bench was built without Embree.
execute_process(
  COMMAND "${BENCH}" --size 16x16 --leaf-sizes 1 --compare embree "${MESH}" -o "${OUT}"
  RESULT_VARIABLE result OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(err MATCHES "built without Embree")
  message("kdrt test skipped: kdrt-bench was built without Embree (tools/setup.sh installs libembree-dev)")
  return()
endif()
if(NOT result EQUAL 0)
  message(FATAL_ERROR "kdrt-bench --compare embree failed (${result}): ${err}")
endif()
file(STRINGS "${OUT}" lines)
list(LENGTH lines n)
if(NOT n EQUAL 3)
  message(FATAL_ERROR "expected the header, a kdrt row and an Embree row, got ${n} lines: ${lines}")
endif()
list(GET lines 2 row)
string(REPLACE ";" "|" row "${row}")
# Mesh, MaxLeafSize -1, ElapsedMs, Builder embree, Triangles, BuildMs, TraceMs, MRaysPerSec, 6 empty
# tree statistics, Mismatches 0.
if(NOT row MATCHES "^OCTAHEDRON\\|-1\\|[0-9]+\\|embree\\|[0-9]+\\|[0-9.]+\\|[0-9.]+\\|[0-9.]+\\|\\|\\|\\|\\|\\|0\\|")
  message(FATAL_ERROR "unexpected Embree row: ${row}")
endif()
