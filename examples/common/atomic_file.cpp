#include "common/atomic_file.hpp"

#include "common/interrupt.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

namespace common {

bool check_replaceable(const std::string &path, std::string &error)
{
    struct stat target;
    if (stat(path.c_str(), &target) != 0) return true;  // absent (or unreachable: creating it says why)
    if (!S_ISREG(target.st_mode)) {
        error = "cannot write '" + path + "': it exists and is not a regular file";
        return false;
    }
    if ((target.st_mode & (S_IWUSR | S_IWGRP | S_IWOTH)) == 0 || (access(path.c_str(), W_OK) != 0 && errno == EACCES)) {
        error = "cannot write '" + path + "': it is read-only (make it writable, or remove it, to replace it)";
        return false;
    }
    return true;
}

bool write_atomically(const std::string &path,
                      const std::function<bool(const std::string &temporary, std::string &error)> &write,
                      std::string &error)
{
    if (!check_replaceable(path, error)) return false;
    const std::string what = "cannot write '" + path + "': ";
    // Unique among this process's writers (threads, animation frames) and other processes'.
    static std::atomic<unsigned> counter(0);
    const std::string tmp = path + ".tmp-" + std::to_string(long(getpid())) + "-" + std::to_string(counter++);
    const int slot = remove_on_signal(tmp);
    std::string reason;
    bool done = write(tmp, reason);
    if (!done) {
        error = what + reason;
    } else if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        error = what + "cannot rename " + tmp + " over it: " + std::strerror(errno);
        done = false;
    }
    if (!done) std::remove(tmp.c_str());
    forget_on_signal(slot);
    return done;
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
