// A cap on the heap memory one thread takes through operator new, which common::load_mesh arms
// while Assimp reads a file: a file that claims a billion vertices gets std::bad_alloc at its first
// oversized request instead of the machine's memory.
//
// heap_budget.cpp replaces the global operator new and delete (plain, array, nothrow and sized;
// not the aligned ones, which Assimp does not call). They pass straight through to malloc and
// free; only while a HeapBudget lives on the calling thread do they count its live bytes
// (malloc_usable_size) and refuse a request that would take them past the limit. Every program
// that links kdrt_common gets them, idle outside load_mesh. (Under AddressSanitizer they replace
// its operator new too, so a delete that does not match its new goes unreported.)
#pragma once

#include <cstdint>

namespace common {

class HeapBudget {
public:
    // Arms the cap on this thread: operator new refuses a request of large_request bytes or more
    // that would take the bytes allocated since, less those freed, past `limit`, and a smaller
    // one past twice the limit. Budgets nest; the inner one rules. While armed, memory from
    // operator new comes zeroed.
    static constexpr uint64_t large_request = uint64_t(1) << 20;
    explicit HeapBudget(uint64_t limit);
    ~HeapBudget();  // disarms it (restores the enclosing budget, if any)
    HeapBudget(const HeapBudget &) = delete;
    HeapBudget &operator=(const HeapBudget &) = delete;

    void raise(uint64_t bytes);  // allows `bytes` more
    uint64_t limit() const;
    uint64_t peak() const;       // the most live bytes so far
    uint64_t refused() const;    // the size of the first request refused, 0 if none
    uint64_t live_at_refusal() const;  // the live bytes when it was refused

    // A thread's counters (heap_budget.cpp keeps one per thread).
    struct State {
        bool armed;
        int64_t live, peak, limit;  // live can go negative: blocks from before the budget freed under it
        uint64_t refused, live_at_refusal;
    };

private:
    State saved_;  // the enclosing budget's counters, put back by the destructor
};

}  // namespace common
