# Checks the CSV of the bench_skips_bad_mesh test: the header, then TRIANGLE's rows for leaf sizes
# 0 and 4 with no mismatches, the default (watertight) intersector, the SAH cost of one leaf
# holding the scene's 3 triangles (one block: the default intersection cost, 20) and no SahCosts (a
# median tree) built on 1 thread with the plain queries, a call a ray, although the other two
# inputs were skipped. A CSV without those rows fails.
file(STRINGS "${CSV}" lines)
list(GET lines 0 header)
if(NOT header MATCHES "^Mesh;MaxLeafSize;ElapsedMs;")
  message(FATAL_ERROR "bad header: ${header}")
endif()
list(LENGTH lines n)
if(NOT n EQUAL 3)
  message(FATAL_ERROR "expected 2 rows, got ${n} lines: ${lines}")
endif()
foreach(i 1 2)
  list(GET lines ${i} row)
  string(REPLACE ";" "|" row "${row}")
  if(NOT row MATCHES "^TRIANGLE\\|(0|4)\\|[0-9]+\\|median\\|3\\|.*\\|0\\|256\\|watertight\\|20\\.000\\|\\|1\\|\\|plain\\|root\\|single\\|(scalar|avx2|avx512)$")
    message(FATAL_ERROR "unexpected row: ${row}")
  endif()
endforeach()
