// Output files that appear whole or not at all, for kdrt-render, kdrt-render-mesh and the tools:
// a failed or interrupted write never leaves a truncated image or export behind.
#pragma once

#include <functional>
#include <string>

namespace common {

// Creates or replaces `path` once `write` has filled a temporary file beside it (write gets the
// temporary's name; it returns false with a message on failure). The temporary is then renamed
// over path; on any failure it is removed and path is left as it was. A path that exists and is
// not a regular file is refused. Errors read "cannot write 'PATH': ...".
bool write_atomically(const std::string &path,
                      const std::function<bool(const std::string &temporary, std::string &error)> &write,
                      std::string &error);

// The same for bytes already in memory (an encoded PNG, a JSON or OBJ text).
bool write_file_atomically(const std::string &path, const std::string &bytes, std::string &error);

}  // namespace common
