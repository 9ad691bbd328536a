# Runs COMMAND (its arguments separated by '|') and requires it to fail cleanly: a non-zero exit
# status and standard error matching EXPECT. Options:
#   STDOUT=FILE    its standard output goes to FILE (/dev/full: every write fails, ENOSPC)
#   FILE_LIMIT=N   it runs under bash's `ulimit -f N` (N KiB) with SIGXFSZ ignored, so a
#                  write that would grow a file past that fails (EFBIG), as on a full disk
#   KEEP=FILE      FILE holds "the old file" before the run and must hold it after, with no
#                  temporary FILE.tmp-* left beside it
include("${CMAKE_CURRENT_LIST_DIR}/expect_failure.cmake")
string(REPLACE "|" ";" command "${COMMAND}")
if(DEFINED FILE_LIMIT)
  set(command bash -c "ulimit -f ${FILE_LIMIT} && trap '' XFSZ && exec \"$@\"" bash ${command})
endif()
if(DEFINED KEEP)
  file(GLOB leftovers "${KEEP}.tmp-*")
  if(leftovers)
    file(REMOVE ${leftovers})
  endif()
  file(WRITE "${KEEP}" "the old file")
endif()
if(NOT DEFINED STDOUT)
  set(STDOUT /dev/null)
endif()
expect_failure("${EXPECT}" "${STDOUT}" ${command})
if(DEFINED KEEP)
  file(READ "${KEEP}" text)
  if(NOT text STREQUAL "the old file")
    message(FATAL_ERROR "${KEEP} was changed")
  endif()
  file(GLOB leftovers "${KEEP}.tmp-*")
  if(leftovers)
    message(FATAL_ERROR "temporaries left behind: ${leftovers}")
  endif()
endif()
