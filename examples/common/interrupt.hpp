// What a SIGINT or SIGTERM does to the programs' files: temporaries registered here are removed,
// a registered note is printed on stderr, and the process then dies of the signal as it would
// have (the shell sees "killed by signal"). SIGKILL cannot be caught: after it the temporaries
// stay (OUT.tmp-PID-N beside OUT, see atomic_file.hpp).
#pragma once

#include <string>

namespace common {

// Removes `path` if a SIGINT or SIGTERM arrives before forget_on_signal(slot); the first call
// installs the handlers (not over a signal the process was started ignoring, as nohup does).
// Returns the slot, or -1 when all 64 slots are taken by other threads' files (that file is then
// left behind by a signal, like after SIGKILL).
int remove_on_signal(const std::string &path);
void forget_on_signal(int slot);

// A line the handler writes on stderr before the process dies of the signal (kdrt-bench: where
// its rows are); "" for none.
void note_on_signal(const std::string &line);

}  // namespace common
