#include "common/heap_budget.hpp"

#include <malloc.h>

#include <algorithm>
#include <cstdlib>
#include <new>

namespace {

// Constant-initialised, so operator new reads it without a thread_local constructor or wrapper.
thread_local common::HeapBudget::State state{};

int64_t clamp(uint64_t bytes) { return int64_t(std::min<uint64_t>(bytes, INT64_MAX)); }

void *allocate(std::size_t n)
{
    common::HeapBudget::State &s = state;
    // A large request (an array sized by a header's count) is held to the limit; small ones (the
    // nodes, names and short arrays a reader makes as it goes, where Assimp's readers are least
    // ready for std::bad_alloc) to twice the limit, so that a file cannot fill the budget with
    // one claim and have the next small allocation fail wherever it likes.
    const int64_t ceiling = n >= common::HeapBudget::large_request ? s.limit : s.limit > INT64_MAX / 2 ? INT64_MAX : 2 * s.limit;
    if (s.armed && (n > uint64_t(INT64_MAX - ceiling) || s.live + int64_t(n) > ceiling)) {
        if (!s.refused) s.refused = n, s.live_at_refusal = uint64_t(std::max<int64_t>(s.live, 0));
        throw std::bad_alloc();
    }
    // Under a budget, memory comes zeroed: a reader stopped by std::bad_alloc half way through
    // filling an array of pointers (Assimp's OFF reader: new aiMaterial *[1], then the material)
    // leaves null pointers for its destructors to delete, not whatever the heap held there.
    void *p;
    while (!(p = s.armed ? std::calloc(1, n ? n : 1) : std::malloc(n ? n : 1))) {
        std::new_handler handler = std::get_new_handler();
        if (!handler) throw std::bad_alloc();
        handler();
    }
    if (s.armed) s.peak = std::max(s.peak, s.live += int64_t(malloc_usable_size(p)));
    return p;
}

void release(void *p) noexcept
{
    if (!p) return;
    common::HeapBudget::State &s = state;
    if (s.armed) s.live -= int64_t(malloc_usable_size(p));
    std::free(p);
}

}  // namespace

void *operator new(std::size_t n) { return allocate(n); }
void *operator new[](std::size_t n) { return allocate(n); }
void *operator new(std::size_t n, const std::nothrow_t &) noexcept
{
    try {
        return allocate(n);
    } catch (...) {
        return nullptr;
    }
}
void *operator new[](std::size_t n, const std::nothrow_t &) noexcept
{
    try {
        return allocate(n);
    } catch (...) {
        return nullptr;
    }
}
void operator delete(void *p) noexcept { release(p); }
void operator delete[](void *p) noexcept { release(p); }
void operator delete(void *p, std::size_t) noexcept { release(p); }
void operator delete[](void *p, std::size_t) noexcept { release(p); }
void operator delete(void *p, const std::nothrow_t &) noexcept { release(p); }
void operator delete[](void *p, const std::nothrow_t &) noexcept { release(p); }

namespace common {

HeapBudget::HeapBudget(uint64_t limit) : saved_(state) { state = State{true, 0, 0, clamp(limit), 0, 0}; }

HeapBudget::~HeapBudget()
{
    // What was allocated under this budget and is still live counts for the enclosing one.
    const int64_t live = state.live;
    state = saved_;
    if (state.armed) state.peak = std::max(state.peak, state.live += live);
}

void HeapBudget::raise(uint64_t bytes) { state.limit = clamp(uint64_t(state.limit) + std::min<uint64_t>(bytes, INT64_MAX)); }
uint64_t HeapBudget::limit() const { return uint64_t(state.limit); }
uint64_t HeapBudget::peak() const { return uint64_t(state.peak); }
uint64_t HeapBudget::refused() const { return state.refused; }
uint64_t HeapBudget::live_at_refusal() const { return state.live_at_refusal; }

}  // namespace common
