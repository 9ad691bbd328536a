// Standard output checked like any other file: output lost to a full disk, a closed or broken
// file is an error and a non-zero exit, never exit status 0 with the output cut short.
#pragma once

#include <cstdio>
#include <string>

namespace common {

// Writes `text` to `file` and flushes it. False, with "cannot write NAME: REASON", when any of it
// did not reach the system.
bool write_flushed(std::FILE *file, const std::string &text, const std::string &name, std::string &error);

// The last thing a program's main does: flushes and closes standard output and returns `status`,
// except when a successful run (status 0) lost some of its output: then it prints "PROGRAM:
// cannot write standard output: REASON" on stderr and returns 1. (A failed run has said why.)
int close_stdout(const char *program, int status);

}  // namespace common
