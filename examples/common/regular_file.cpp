#include "common/regular_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace common {

std::string not_regular(const struct stat &st)
{
    if (S_ISREG(st.st_mode)) return "";
    if (S_ISDIR(st.st_mode)) return "it is a directory";
    const char *kind = S_ISFIFO(st.st_mode)   ? "a FIFO"
                       : S_ISCHR(st.st_mode)  ? "a character device"
                       : S_ISBLK(st.st_mode)  ? "a block device"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                                              : "an unknown kind of file";
    return std::string("it is not a regular file (") + kind + ")";
}

std::FILE *open_regular_file(const char *path, struct stat &st, std::string &why)
{
    // O_NONBLOCK: opening a FIFO for reading returns at once instead of waiting for a writer.
    const int fd = ::open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        why = std::strerror(errno);
        return nullptr;
    }
    std::FILE *file = nullptr;
    if (::fstat(fd, &st) != 0)
        why = std::strerror(errno);
    else if (!(why = not_regular(st)).empty())
        ;
    else if (::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK) != 0 || !(file = ::fdopen(fd, "rb")))
        why = std::strerror(errno);
    if (!file) ::close(fd);
    return file;
}

}  // namespace common
