# Checks the CSV of kdrt-bench --save-load on the height field and the octahedron (bench_save_load):
# a FAST and a MEDIUM (the default) row per mesh, in that order, each with its triangles, every
# time a number, the file no larger than the tree's memory and at least its 256-byte header and
# 32-byte mesh record, and the ratios numbers. The run itself fails (exit 1, no row of that mesh)
# when a load fails, a loaded tree saves to other bytes, or a changed mesh is not refused.
include(${CMAKE_CURRENT_LIST_DIR}/bench_csv_rows.cmake)
read_csv_rows("${CSV}"
  "Mesh|Triangles|Quality|BuildMs|SaveMs|LoadMs|LoadInPlaceMs|FingerprintMs|TreeBytes|SavedBytes|FastBuildOverLoad|FastBuildOverLoadInPlace"
  12 "GRID\\|512\\|fast\\|" "GRID\\|512\\|medium\\|" "OCTAHEDRON\\|8\\|fast\\|" "OCTAHEDRON\\|8\\|medium\\|")
set(number "[0-9]+\\.[0-9]+")
foreach(row IN LISTS LINES)
  if(NOT row MATCHES "^[A-Z]+\\|[0-9]+\\|[a-z]+\\|${number}\\|${number}\\|${number}\\|${number}\\|${number}\\|([0-9]+)\\|([0-9]+)\\|${number}\\|${number}$")
    message(FATAL_ERROR "not a row of numbers: ${row}")
  endif()
  set(tree_bytes ${CMAKE_MATCH_1})
  set(saved_bytes ${CMAKE_MATCH_2})
  if(saved_bytes GREATER tree_bytes OR saved_bytes LESS 288)
    message(FATAL_ERROR "a file of ${saved_bytes} bytes for a tree of ${tree_bytes}: ${row}")
  endif()
endforeach()
message(STATUS "kdrt-bench --save-load: ${LINES}")
