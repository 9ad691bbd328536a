#include "common/output.hpp"

#include <cerrno>
#include <cstring>

namespace common {

bool write_flushed(std::FILE *file, const std::string &text, const std::string &name, std::string &error)
{
    errno = 0;
    if (std::fwrite(text.data(), 1, text.size(), file) == text.size() && std::fflush(file) == 0) return true;
    error = "cannot write " + name + ": " + (errno ? std::strerror(errno) : "write error");
    return false;
}

int close_stdout(const char *program, int status)
{
    // glibc keeps what a failed write could not write, so the flush fails again with the reason.
    errno = 0;
    const bool flushed = std::fflush(stdout) == 0 && !std::ferror(stdout);
    int reason = errno;
    errno = 0;
    const bool closed = std::fclose(stdout) == 0;
    if (!closed && !reason) reason = errno;
    // A standard output closed before the start (EBADF) that nothing was written to is no error.
    if (status != 0 || (flushed && (closed || reason == EBADF))) return status;  // a failed run said why
    std::fprintf(stderr, "%s: cannot write standard output: %s\n", program,
                 reason ? std::strerror(reason) : "write error");
    return 1;
}

}  // namespace common
