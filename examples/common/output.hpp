// Standard output checked like any other file: output lost to a full disk, a closed or broken
// file is an error and a non-zero exit, never exit status 0 with the output cut short.
#pragma once

#include <cstdio>
#include <exception>
#include <new>
#include <string>

namespace common {

// Writes `text` to `file` and flushes it. False, with "cannot write NAME: REASON", when any of it
// did not reach the system.
bool write_flushed(std::FILE *file, const std::string &text, const std::string &name, std::string &error);

// The last thing a program's main does: flushes and closes standard output and returns `status`,
// except when a successful run (status 0) lost some of its output: then it prints "PROGRAM:
// cannot write standard output: REASON" on stderr and returns 1. (A failed run has said why.)
int close_stdout(const char *program, int status);

// A bad command line, thrown by a program's run() for guarded_main() to report.
struct UsageError {
    std::string message;
};

// A command-line program's main: returns run()'s status, or reports what it threw as one line
// "PROGRAM: MESSAGE" on stderr with exit status 2 for a UsageError and 1 for anything else (out
// of memory included); then close_stdout().
template <typename Run>
int guarded_main(const char *program, const Run &run)
{
    int status = 1;
    try {
        status = run();
    } catch (const UsageError &e) {
        std::fprintf(stderr, "%s: %s\n", program, e.message.c_str()), status = 2;
    } catch (const std::bad_alloc &) {
        std::fprintf(stderr, "%s: out of memory\n", program), status = 1;
    } catch (const std::exception &e) {
        std::fprintf(stderr, "%s: %s\n", program, e.what()), status = 1;
    }
    return close_stdout(program, status);
}

}  // namespace common
