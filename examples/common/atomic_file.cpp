#include "common/atomic_file.hpp"

#include "common/interrupt.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

namespace common {
namespace {

// PATH.tmp-PID-N: unique among this process's writers (threads, animation frames) and other
// processes'.
std::string temporary_for(const std::string &path)
{
    static std::atomic<unsigned> counter(0);
    return path + ".tmp-" + std::to_string(long(getpid())) + "-" + std::to_string(counter++);
}

// The folder a new file `path` would be created in, as the user wrote it ("." for a bare name).
std::string folder_of(const std::string &path)
{
    const size_t slash = path.find_last_of('/');
    if (slash == std::string::npos) return ".";
    return slash == 0 ? "/" : path.substr(0, slash);
}

// Every occurrence of `from` in `text` replaced by `to`.
std::string replace_all(std::string text, const std::string &from, const std::string &to)
{
    for (size_t at = text.find(from); !from.empty() && at != std::string::npos; at = text.find(from, at + to.size()))
        text.replace(at, from.size(), to);
    return text;
}

}  // namespace

bool check_replaceable(const std::string &path, std::string &error)
{
    const std::string what = "cannot write '" + path + "': ";
    if (path.empty() || path.back() == '/') {
        error = what + "it names a folder, not a file";
        return false;
    }
    struct stat target;
    if (stat(path.c_str(), &target) == 0) {
        if (!S_ISREG(target.st_mode)) {
            error = what + "it exists and is not a regular file";
            return false;
        }
        if ((target.st_mode & (S_IWUSR | S_IWGRP | S_IWOTH)) == 0 || (access(path.c_str(), W_OK) != 0 && errno == EACCES)) {
            error = what + "it is read-only (make it writable, or remove it, to replace it)";
            return false;
        }
    } else if (errno != ENOENT && errno != ENOTDIR) {
        error = what + std::strerror(errno);  // a folder on the way that cannot be searched, a loop...
        return false;
    }
    // The file is replaced by a temporary created beside it: prove the folder takes one, with a
    // probe named as the temporaries are, created (never over an existing file) and removed.
    const std::string folder = folder_of(path);
    struct stat dir;
    if (stat(folder.c_str(), &dir) != 0) {
        error = what + (errno == ENOENT   ? "the folder '" + folder + "' does not exist"
                        : errno == ENOTDIR ? "'" + folder + "' is not a folder"
                                           : "cannot reach the folder '" + folder + "': " + std::strerror(errno));
        return false;
    }
    if (!S_ISDIR(dir.st_mode)) {
        error = what + "'" + folder + "' is not a folder";
        return false;
    }
    int fd = -1, open_errno = EEXIST;
    for (int attempt = 0; fd < 0 && open_errno == EEXIST && attempt < 8; ++attempt) {  // EEXIST: one a SIGKILL left
        const std::string probe = temporary_for(path);
        const int slot = remove_on_signal(probe);
        fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
        open_errno = errno;
        if (fd >= 0) {
            ::close(fd);
            ::unlink(probe.c_str());
        }
        forget_on_signal(slot);
    }
    if (fd < 0) {
        error = what + "cannot create a file in '" + folder + "': " + std::strerror(open_errno);
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
    const std::string tmp = temporary_for(path);
    const int slot = remove_on_signal(tmp);
    std::string reason;
    bool done = write(tmp, reason);
    if (!done) {
        // The user knows the path, not the temporary: a writer's message that names it names
        // the path instead.
        error = what + replace_all(reason, tmp, path);
    } else if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        error = what + "cannot replace it: " + std::strerror(errno);
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
            reason = std::strerror(errno);
            return false;
        }
        const bool written = std::fwrite(bytes.data(), 1, bytes.size(), file) == bytes.size();
        const int write_errno = errno;
        const bool closed = std::fclose(file) == 0;  // a full disk can show only here
        if (!written || !closed) {
            reason = std::strerror(written ? errno : write_errno);
            return false;
        }
        return true;
    }, error);
}

}  // namespace common
