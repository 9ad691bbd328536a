#include "common/interrupt.hpp"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <mutex>

namespace common {
namespace {

// The handler may only read memory that is not being changed under it and call what POSIX lists
// as async-signal-safe (unlink, write, strlen, sigaction, raise). A slot is free, being filled,
// registered, or claimed by the handler; only the handler takes a registered slot to claimed, so
// the path it reads is never rewritten while it reads it.
enum : int { kFree, kFilling, kRegistered, kClaimed };
constexpr int kSlots = 64;
constexpr std::size_t kBytes = 4096;
static_assert(std::atomic<int>::is_always_lock_free, "the handler needs lock-free atomics");

struct Slot {
    std::atomic<int> state{kFree};
    char path[kBytes];
};
Slot slots[kSlots];
std::atomic<int> note_state{kFree};
char note[kBytes];
std::mutex note_mutex;

const int kSignals[2] = {SIGINT, SIGTERM};
struct sigaction previous[2];  // what each signal did before, restored before it is raised again

extern "C" void on_signal(int sig)
{
    for (Slot &slot : slots) {
        int expected = kRegistered;
        if (slot.state.compare_exchange_strong(expected, kClaimed)) unlink(slot.path);
    }
    int expected = kRegistered;
    if (note_state.compare_exchange_strong(expected, kClaimed)) {
        const ssize_t written = write(STDERR_FILENO, note, std::strlen(note));
        (void)written;  // nothing more can be done about stderr here
    }
    // Die of the signal as before (the default: terminate), once this handler returns.
    sigaction(sig, &previous[sig == SIGTERM], nullptr);
    raise(sig);
}

void install()
{
    static std::once_flag once;
    std::call_once(once, [] {
        for (int i = 0; i < 2; ++i) {
            struct sigaction current;
            sigaction(kSignals[i], nullptr, &current);
            if (current.sa_handler == SIG_IGN) continue;  // started ignoring it (nohup, a background job)
            previous[i] = current;
            struct sigaction ours = {};
            ours.sa_handler = on_signal;
            sigemptyset(&ours.sa_mask);
            for (int s : kSignals) sigaddset(&ours.sa_mask, s);  // one handler run at a time
            sigaction(kSignals[i], &ours, nullptr);
        }
    });
}

}  // namespace

int remove_on_signal(const std::string &path)
{
    install();
    if (path.size() >= kBytes) return -1;
    for (int i = 0; i < kSlots; ++i) {
        int expected = kFree;
        if (!slots[i].state.compare_exchange_strong(expected, kFilling)) continue;
        std::memcpy(slots[i].path, path.c_str(), path.size() + 1);
        slots[i].state.store(kRegistered);
        return i;
    }
    return -1;
}

void forget_on_signal(int slot)
{
    if (slot < 0 || slot >= kSlots) return;
    int expected = kRegistered;
    slots[slot].state.compare_exchange_strong(expected, kFree);
}

void note_on_signal(const std::string &line)
{
    install();
    std::lock_guard<std::mutex> lock(note_mutex);
    int expected = note_state.load();
    if (expected == kClaimed || !note_state.compare_exchange_strong(expected, kFilling)) return;  // being printed
    const std::string text = line.empty() ? "" : line.substr(0, kBytes - 2) + "\n";
    std::memcpy(note, text.c_str(), text.size() + 1);
    note_state.store(text.empty() ? kFree : kRegistered);
}

}  // namespace common
