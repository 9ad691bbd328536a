#include "common/atomic_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

namespace common {

bool write_atomically(const std::string &path,
                      const std::function<bool(const std::string &temporary, std::string &error)> &write,
                      std::string &error)
{
    const std::string what = "cannot write '" + path + "': ";
    struct stat target;
    if (stat(path.c_str(), &target) == 0 && !S_ISREG(target.st_mode)) {
        error = what + "it exists and is not a regular file";
        return false;
    }
    // Unique among this process's writers (threads, animation frames) and other processes'.
    static std::atomic<unsigned> counter(0);
    const std::string tmp = path + ".tmp-" + std::to_string(long(getpid())) + "-" + std::to_string(counter++);
    std::string reason;
    if (!write(tmp, reason)) {
        error = what + reason;
        std::remove(tmp.c_str());
        return false;
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        error = what + "cannot rename " + tmp + " over it: " + std::strerror(errno);
        std::remove(tmp.c_str());
        return false;
    }
    return true;
}

bool write_file_atomically(const std::string &path, const std::string &bytes, std::string &error)
{
    return write_atomically(path, [&](const std::string &tmp, std::string &reason) {
        FILE *file = std::fopen(tmp.c_str(), "wb");
        if (!file) {
            reason = "cannot create " + tmp + ": " + std::strerror(errno);
            return false;
        }
        const bool written = std::fwrite(bytes.data(), 1, bytes.size(), file) == bytes.size();
        const int write_errno = errno;
        const bool closed = std::fclose(file) == 0;  // a full disk can show only here
        if (!written || !closed) {
            reason = "cannot write " + tmp + ": " + std::strerror(written ? errno : write_errno);
            return false;
        }
        return true;
    }, error);
}

}  // namespace common
