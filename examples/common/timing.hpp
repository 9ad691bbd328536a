// Wall-clock timing for the bench: one stopwatch, and a timed loop over rays split across threads.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <thread>
#include <vector>

namespace common {

struct Stopwatch {
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
    double ms() const { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count(); }
};

inline unsigned all_cores() { return std::max(1u, std::thread::hardware_concurrency()); }

// Runs body(i) for i in [0, count) on `threads` threads, each a contiguous range, and returns the
// wall time in milliseconds. With one thread no thread is started.
template <typename Body>
double timed_parallel(size_t count, unsigned threads, Body &&body) {
    threads = std::max(1u, threads);
    Stopwatch clock;
    if (threads == 1) {
        for (size_t i = 0; i < count; ++i) body(i);
        return clock.ms();
    }
    std::vector<std::thread> pool;
    for (unsigned w = 0; w < threads; ++w)
        pool.emplace_back([&, w] {
            size_t begin = count * w / threads, end = count * (w + 1) / threads;
            for (size_t i = begin; i < end; ++i) body(i);
        });
    for (auto &t : pool) t.join();
    return clock.ms();
}

}  // namespace common
