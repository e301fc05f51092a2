// Replaces every global operator new/delete with versions that count
// allocations, for the real-time tests ("nothing on the per-frame path
// allocates"). Include it in exactly ONE source file of a test binary: it
// defines the replacement functions, which apply to the whole binary.
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

namespace stemd::test {

inline std::atomic<long> g_allocations{0};
// A thread that may allocate (the live view's server and its client, which
// are not on the per-frame path) marks itself; its allocations are not counted.
inline thread_local bool t_uncounted = false;
inline void stop_counting_this_thread() { t_uncounted = true; }

// Heap allocations so far in this process (every form of operator new),
// except those of threads that called stop_counting_this_thread().
inline long allocations() { return g_allocations.load(std::memory_order_relaxed); }
inline void count_one()
{
    if (!t_uncounted)
        g_allocations.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace stemd::test

// new is malloc, so free is the matching release. GCC cannot see that through inlining.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

void* operator new(std::size_t size)
{
    stemd::test::count_one();
    if (void* p = std::malloc(size == 0 ? 1 : size))
        return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
// nothrow (std::stable_sort's buffer) and over-aligned (the rings' cache-line
// members) forms too, so that every allocation is counted and every release
// matches its allocation under ASan.
void* operator new(std::size_t size, const std::nothrow_t&) noexcept
{
    stemd::test::count_one();
    return std::malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t& tag) noexcept { return operator new(size, tag); }
void* operator new(std::size_t size, std::align_val_t align)
{
    stemd::test::count_one();
    const auto a = static_cast<std::size_t>(align);
    if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a))
        return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t align) { return operator new(size, align); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
