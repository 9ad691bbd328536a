// A kdrt_scheduler on std::thread, for the bench, the examples and the tests: `threads` workers
// (the caller's thread is one of them) kept for the scheduler's life, as a game engine's job
// system is, that take task indices in turn. kdrt's build calls run() many times (each large node
// at the top of a parallel build is binned and split in chunks), so starting threads per run()
// would cost more than the work. A game engine would hand kdrt its own job system instead; the
// tree is the same either way.
#pragma once

#include "kdrt.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace common {

class ThreadScheduler {
public:
    // threads 0: every core the machine has.
    explicit ThreadScheduler(unsigned threads = 0)
        : threads_(threads ? threads : std::max(1u, std::thread::hardware_concurrency())) {
        for (unsigned w = 1; w < threads_; ++w) workers_.emplace_back([this] { serve(); });
    }
    ThreadScheduler(const ThreadScheduler &) = delete;
    ThreadScheduler &operator=(const ThreadScheduler &) = delete;
    ~ThreadScheduler() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
        }
        wake_.notify_all();
        for (std::thread &t : workers_) t.join();
    }

    unsigned threads() const { return threads_; }

    // For kdrt_build_options.scheduler; valid while this object lives. Runs from several threads
    // at once take turns.
    kdrt_scheduler hooks() {
        kdrt_scheduler s;
        s.run = &ThreadScheduler::run;
        s.user = this;
        return s;
    }

private:
    // Runs task(data, 0 .. count - 1) on the caller and the workers; returns when all are done.
    static void run(void *user, kdrt_task_fn task, void *data, uint32_t count) {
        ThreadScheduler *self = static_cast<ThreadScheduler *>(user);
        std::lock_guard<std::mutex> one_run_at_a_time(self->run_mutex_);
        {
            std::lock_guard<std::mutex> lock(self->mutex_);
            self->task_ = task, self->data_ = data, self->count_ = count;
            self->next_ = 0;
            self->busy_ = self->workers_.size();
            ++self->generation_;
        }
        self->wake_.notify_all();
        self->work();
        std::unique_lock<std::mutex> lock(self->mutex_);
        self->done_.wait(lock, [self] { return self->busy_ == 0; });
    }

    void work() {
        for (uint32_t i = next_++; i < count_; i = next_++) task_(data_, i);
    }

    void serve() {
        uint64_t seen = 0;
        std::unique_lock<std::mutex> lock(mutex_);
        for (;;) {
            wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
            if (stop_) return;
            seen = generation_;
            lock.unlock();
            work();
            lock.lock();
            if (--busy_ == 0) done_.notify_one();
        }
    }

    unsigned threads_;
    std::vector<std::thread> workers_;
    std::mutex run_mutex_, mutex_;
    std::condition_variable wake_, done_;
    bool stop_ = false;
    uint64_t generation_ = 0;
    size_t busy_ = 0;
    // The current run's job, set under mutex_ before generation_ moves on.
    kdrt_task_fn task_ = nullptr;
    void *data_ = nullptr;
    uint32_t count_ = 0;
    std::atomic<uint32_t> next_{0};
};

}  // namespace common
