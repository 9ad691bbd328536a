// Output files that appear whole or not at all, for kdrt-render, kdrt-render-mesh and the tools:
// a failed or interrupted write never leaves a truncated image or export behind.
#pragma once

#include <functional>
#include <string>

namespace common {

// Whether `path` may be created or replaced: it does not exist, or it is a regular file that is
// not read-only (a file with no write permission for this user, or none for anyone: root too is
// refused it, since rename() would replace it regardless). Errors read "cannot write 'PATH': ...".
bool check_replaceable(const std::string &path, std::string &error);

// Creates or replaces `path` once `write` has filled a temporary file beside it (write gets the
// temporary's name, PATH.tmp-PID-N; it returns false with a message on failure). The temporary is
// then renamed over path; on any failure it is removed and path is left as it was, and so on a
// SIGINT or SIGTERM (interrupt.hpp); a SIGKILL leaves it. A path check_replaceable refuses is
// refused first. Errors read "cannot write 'PATH': ...".
bool write_atomically(const std::string &path,
                      const std::function<bool(const std::string &temporary, std::string &error)> &write,
                      std::string &error);

// The same for bytes already in memory (an encoded PNG, a JSON or OBJ text).
bool write_file_atomically(const std::string &path, const std::string &bytes, std::string &error);

}  // namespace common
