# kdrt-bench --compare embree on the octahedron: an Embree row beside kdrt's, with no mismatch
# against the oracle; then --batch single,batch,packet8,packet16 on primary and shadow rays: kdrt's
# single and batch rows, and Embree's four (rtcIntersect1, rtcIntersect1M, rtcIntersect8/16, and
# their occluded forms), each named in the Call column with no mismatch. The frame is 17x13, so
# the last packet of 8 and of 16 is short, and --batch-size 50 leaves a short last chunk.
# Reported as skipped when this kdrt-bench was built without Embree.
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
# tree statistics, Mismatches 0, ..., Call single, Kernel empty.
if(NOT row MATCHES "^OCTAHEDRON\\|-1\\|[0-9]+\\|embree\\|[0-9]+\\|[0-9.]+\\|[0-9.]+\\|[0-9.]+\\|\\|\\|\\|\\|\\|0\\|.*\\|single\\|$")
  message(FATAL_ERROR "unexpected Embree row: ${row}")
endif()

foreach(kind primary shadow)
  execute_process(
    COMMAND "${BENCH}" --size 17x13 --leaf-sizes 1 --rays ${kind} --start root --compare embree
            --batch single,batch,packet8,packet16 --batch-size 50 "${MESH}" -o "${OUT}"
    RESULT_VARIABLE result OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "kdrt-bench --batch single,batch,packet8,packet16 --rays ${kind} failed (${result}): ${err}")
  endif()
  file(STRINGS "${OUT}" lines)
  list(LENGTH lines n)
  if(NOT n EQUAL 7)
    message(FATAL_ERROR "--rays ${kind}: expected the header, 2 kdrt rows and 4 Embree rows, got ${n} lines: ${lines}")
  endif()
  set(expected "sah|single" "sah|batch" "embree|single" "embree|batch" "embree|packet8" "embree|packet16")
  foreach(i RANGE 1 6)
    list(GET lines ${i} row)
    string(REPLACE ";" "|" row "${row}")
    math(EXPR k "${i} - 1")
    list(GET expected ${k} builder_call)
    string(REPLACE "|" ";" pair "${builder_call}")
    list(GET pair 0 builder)
    list(GET pair 1 call)
    # Mismatches, then ReferenceRays, both whole numbers: Mismatches must be 0.
    if(NOT row MATCHES "^OCTAHEDRON\\|-?[0-9]+\\|[0-9]+\\|${builder}\\|.*\\|0\\|[0-9]+\\|[a-z]*\\|[0-9.]*\\|[0-9:.]*\\|1\\|[a-z]+\\|[a-z]*\\|[a-z]*\\|${call}\\|[a-z0-9]*$")
      message(FATAL_ERROR "--rays ${kind}: row ${i} is not ${builder}'s ${call} row with no mismatch: ${row}")
    endif()
  endforeach()
endforeach()
message(STATUS "Embree's row beside kdrt's; with --batch, kdrt's single and batch rows and Embree's four, on primary and shadow rays")
