// Output files that appear whole or not at all, for kdrt-render, kdrt-render-mesh and the tools:
// a failed or interrupted write never leaves a truncated image or export behind.
#pragma once

#include <functional>
#include <string>

namespace common {

// Whether `path` may be created or replaced by write_atomically: for a program to call before its
// long work, so that an unwritable output fails at once. True when
//   - path is not there, or is a regular file that is not read-only (a file with no write
//     permission for this user, or none for anyone: root too is refused it, since rename() would
//     replace it regardless), and
//   - its folder exists and a new file can be created in it: a probe named as the temporaries
//     are (PATH.tmp-PID-N) is created there (O_CREAT | O_EXCL, never over a file) and removed at
//     once (and on a SIGINT or SIGTERM in between).
// Otherwise false, and error is one line naming `path` as given (never a temporary) and the
// reason: "cannot write 'PATH': it exists and is not a regular file" (a folder, a device...),
// "... it is read-only (...)", "... the folder 'DIR' does not exist", "... 'DIR' is not a folder",
// "... cannot create a file in 'DIR': REASON" (read-only folder or file system, /proc, a full
// inode table...). What it cannot promise: that the disk has room for the file (a full disk shows
// only when writing), nor that nothing changes between the check and the write (write_atomically
// checks again).
bool check_replaceable(const std::string &path, std::string &error);

// Creates or replaces `path` once `write` has filled a temporary file beside it (write gets the
// temporary's name, PATH.tmp-PID-N; it returns false with a message on failure). The temporary is
// then renamed over path; on any failure it is removed and path is left as it was, and so on a
// SIGINT or SIGTERM (interrupt.hpp); a SIGKILL leaves it. A path check_replaceable refuses is
// refused first. Errors read "cannot write 'PATH': REASON", naming path and never the temporary:
// `write`'s own message is the REASON, with the temporary's name in it replaced by path.
bool write_atomically(const std::string &path,
                      const std::function<bool(const std::string &temporary, std::string &error)> &write,
                      std::string &error);

// The same for bytes already in memory (an encoded PNG, a JSON or OBJ text).
bool write_file_atomically(const std::string &path, const std::string &bytes, std::string &error);

}  // namespace common
