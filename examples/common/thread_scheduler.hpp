// A kdrt_scheduler on std::thread, for the bench, the examples and the tests: each run() starts
// up to `threads` workers (the caller's thread is one of them) that take task indices in turn.
// A game engine would hand kdrt its own job system instead; the tree is the same either way.
#pragma once

#include "kdrt.h"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace common {

class ThreadScheduler {
public:
    // threads 0: every core the machine has.
    explicit ThreadScheduler(unsigned threads = 0)
        : threads_(threads ? threads : std::max(1u, std::thread::hardware_concurrency())) {}

    unsigned threads() const { return threads_; }

    // For kdrt_build_options.scheduler; valid while this object lives.
    kdrt_scheduler hooks() {
        kdrt_scheduler s;
        s.run = &ThreadScheduler::run;
        s.user = this;
        return s;
    }

private:
    static void run(void *user, kdrt_task_fn task, void *data, uint32_t count) {
        const ThreadScheduler *self = static_cast<const ThreadScheduler *>(user);
        std::atomic<uint32_t> next(0);
        auto work = [&] {
            for (uint32_t i = next++; i < count; i = next++) task(data, i);
        };
        std::vector<std::thread> helpers;
        for (unsigned w = 1; w < std::min<uint64_t>(self->threads_, count); ++w) helpers.emplace_back(work);
        work();
        for (std::thread &t : helpers) t.join();
    }

    unsigned threads_;
};

}  // namespace common
