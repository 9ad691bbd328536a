# check_whole_rows(FILE MIN_ROWS): FILE is a leaf-size CSV of kdrt-bench cut only between lines:
# the header, then at least MIN_ROWS rows, each ending in a newline with every column there.
# Sets ROWS in the caller to the number of rows.
function(check_whole_rows file min_rows)
  file(READ "${file}" text)
  if(NOT text MATCHES "\n$")
    message(FATAL_ERROR "${file} ends in a partial line")
  endif()
  # ';' separates CMake list items too: make the fields '|' first, then the lines a list.
  string(REPLACE ";" "|" text "${text}")
  string(STRIP "${text}" text)
  string(REPLACE "\n" ";" lines "${text}")
  list(POP_FRONT lines header)
  if(NOT header MATCHES "^Mesh\\|MaxLeafSize\\|ElapsedMs\\|")
    message(FATAL_ERROR "${file}: bad header: ${header}")
  endif()
  string(REGEX REPLACE "[^|]" "" separators "${header}")
  string(LENGTH "${separators}" columns)
  foreach(row IN LISTS lines)
    string(REGEX REPLACE "[^|]" "" separators "${row}")
    string(LENGTH "${separators}" c)
    # The last six columns: BuildThreads, Quality (empty for the median builder), Query, Start,
    # Call, Kernel.
    if(NOT c EQUAL columns OR NOT row MATCHES "^[A-Z0-9_]+\\|[0-9]+\\|[0-9]+\\|median\\|.*\\|[0-9]+\\|[a-z]*\\|plain\\|root\\|single\\|(scalar|avx2|avx512)$")
      message(FATAL_ERROR "${file}: incomplete or wrong row: ${row}")
    endif()
  endforeach()
  list(LENGTH lines rows)
  if(rows LESS min_rows)
    message(FATAL_ERROR "${file}: ${rows} rows, expected at least ${min_rows}")
  endif()
  set(ROWS ${rows} PARENT_SCOPE)
endfunction()

# read_csv_rows(FILE HEADER): FILE's rows after a header that must be HEADER, with '|' for ';'
# (which separates CMake list items too). Sets LINES in the caller to the list of rows.
function(read_csv_rows file expected_header)
  file(READ "${file}" text)
  string(REPLACE ";" "|" text "${text}")
  string(STRIP "${text}" text)
  string(REPLACE "\n" ";" lines "${text}")
  list(POP_FRONT lines header)
  if(NOT header STREQUAL "${expected_header}")
    message(FATAL_ERROR "${file}: bad header: ${header}")
  endif()
  set(LINES "${lines}" PARENT_SCOPE)
endfunction()
