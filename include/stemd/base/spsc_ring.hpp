// A bounded lock-free single-producer/single-consumer ring, in the manner of
// rigtorp/SPSCQueue: capacity fixed at construction, every cell allocated
// there, head and tail on their own cache lines, acquire/release only.
//
//   producer: try_push(v), or claim() + publish() to build an item in place;
//             try_push_overwrite(v, evicted) for the overwrite_oldest policy
//   consumer: front() + pop(), or try_pop(out)
//
// head_ and tail_ are 64-bit counters that only grow (the cell is
// counter % capacity), so full is tail - head == capacity with no slack cell
// and no ABA: 2^64 items never happen.
//
// Overwrite (the overwrite_oldest policy) lives here rather than on the
// capture side because only the ring knows which item is oldest: the
// producer takes the oldest item back by moving head_ forward with a CAS,
// and the consumer claims items with a CAS too, so each item goes to exactly
// one of them. That needs cells the producer may rewrite while the consumer
// reads them, so it is offered only for small trivially copyable items
// (FrameSlot pointers), whose cells are then std::atomic<T>. Large items
// (Detections) use plain cells, in-place claim()/publish(), front()/pop().
//
// Drops are counted where they happen: try_push on a full ring counts
// dropped(), try_push_overwrite counts overwritten(). Both are written by the
// producer only and may be read from any thread (relaxed; for status).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <stdexcept>
#include <type_traits>
#include <utility>

namespace stemd::base {

// std::hardware_destructive_interference_size is 64 on every target we build
// for; GCC warns when the constant appears in a header (ABI can differ with
// -mtune), so the value is written out.
inline constexpr std::size_t kCacheLineBytes = 64;

template <class T>
inline constexpr bool kAtomicCells =
    std::is_trivially_copyable_v<T> && sizeof(T) <= sizeof(std::uint64_t) && std::atomic<T>::is_always_lock_free;

template <class T>
class SpscRing {
    using Cell = std::conditional_t<kAtomicCells<T>, std::atomic<T>, T>;

public:
    // Allocates `capacity` cells (value-initialised); nothing is allocated later.
    explicit SpscRing(std::size_t capacity) : capacity_(capacity), cells_(new Cell[capacity]())
    {
        if (capacity == 0)
            throw std::invalid_argument("SpscRing: capacity must be at least 1");
    }
    SpscRing(const SpscRing&) = delete;
    SpscRing& operator=(const SpscRing&) = delete;

    std::size_t capacity() const { return capacity_; }

    // --- producer ------------------------------------------------------------

    // False (and dropped() + 1) if the ring is full; the item is not taken.
    bool try_push(const T& value)
    {
        if (!has_room()) {
            dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
            return false;
        }
        if constexpr (kAtomicCells<T>)
            cells_[index(tail_)].store(value, std::memory_order_relaxed);
        else
            cells_[index(tail_)] = value;
        publish();
        return true;
    }

    // In place: the next free cell, or nullptr if the ring is full (not
    // counted: the caller decides whether that is a drop). Fill it, then
    // publish(). Plain cells only.
    T* claim() requires(!kAtomicCells<T>) { return has_room() ? &cells_[index(tail_)] : nullptr; }
    void publish() { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

    // overwrite_oldest: always pushes. If the ring was full, the oldest item
    // is taken back into `evicted`, overwritten() + 1, and true is returned;
    // the producer owns `evicted` again (for FrameSlot pointers: reuse the slot).
    bool try_push_overwrite(const T& value, T& evicted) requires kAtomicCells<T>
    {
        bool took_oldest = false;
        const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
        std::uint64_t head = head_.load(std::memory_order_acquire);
        while (tail - head == capacity_) {
            const T oldest = cells_[index(head)].load(std::memory_order_relaxed);
            // Success: the consumer can no longer claim `oldest`. Failure: the
            // consumer took it (head moved), so there is room now.
            if (head_.compare_exchange_weak(head, head + 1, std::memory_order_acq_rel, std::memory_order_acquire)) {
                evicted = oldest;
                took_oldest = true;
                overwritten_.store(overwritten_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
                break;
            }
        }
        head_cache_ = head_.load(std::memory_order_acquire);
        cells_[index(tail)].store(value, std::memory_order_relaxed);
        tail_.store(tail + 1, std::memory_order_release);
        return took_oldest;
    }

    // --- consumer ------------------------------------------------------------

    // The oldest item, or nullptr if empty; pop() releases it. Plain cells only.
    T* front() requires(!kAtomicCells<T>)
    {
        const std::uint64_t head = head_.load(std::memory_order_relaxed);
        if (head == tail_cache_) {
            tail_cache_ = tail_.load(std::memory_order_acquire);
            if (head == tail_cache_)
                return nullptr;
        }
        return &cells_[index(head)];
    }
    void pop() requires(!kAtomicCells<T>)
    {
        head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
    }

    // Moves the oldest item into `out`; false if empty.
    bool try_pop(T& out)
    {
        if constexpr (kAtomicCells<T>) {
            // The producer may take the oldest item back (try_push_overwrite),
            // so the item is ours only once the CAS on head_ succeeds.
            std::uint64_t head = head_.load(std::memory_order_acquire);
            for (;;) {
                // `<=`, not `==`: an overwrite moves head_ past this thread's
                // cached tail, and a cell at or beyond the real tail holds an
                // item that is already gone.
                if (tail_cache_ <= head) {
                    tail_cache_ = tail_.load(std::memory_order_acquire);
                    if (tail_cache_ <= head)
                        return false;
                }
                const T value = cells_[index(head)].load(std::memory_order_relaxed);
                if (head_.compare_exchange_weak(head, head + 1, std::memory_order_acq_rel, std::memory_order_acquire)) {
                    out = value;
                    return true;
                }
            }
        } else {
            T* item = front();
            if (item == nullptr)
                return false;
            out = std::move(*item);
            pop();
            return true;
        }
    }

    // --- either side, approximate while the other side runs ------------------

    std::size_t size() const
    {
        const std::uint64_t head = head_.load(std::memory_order_acquire);
        const std::uint64_t tail = tail_.load(std::memory_order_acquire);
        return tail >= head ? static_cast<std::size_t>(tail - head) : 0;
    }
    bool empty() const { return size() == 0; }
    std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
    std::uint64_t overwritten() const { return overwritten_.load(std::memory_order_relaxed); }

private:
    std::size_t index(std::uint64_t counter) const { return static_cast<std::size_t>(counter % capacity_); }
    std::size_t index(const std::atomic<std::uint64_t>& counter) const
    {
        return index(counter.load(std::memory_order_relaxed));
    }

    bool has_room()
    {
        const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
        if (tail - head_cache_ == capacity_) {
            head_cache_ = head_.load(std::memory_order_acquire);
            if (tail - head_cache_ == capacity_)
                return false;
        }
        return true;
    }

    const std::size_t capacity_;
    const std::unique_ptr<Cell[]> cells_;

    // Consumer side: head_ (also advanced by the producer's overwrite CAS)
    // and the consumer's cached copy of tail_.
    alignas(kCacheLineBytes) std::atomic<std::uint64_t> head_{0};
    std::uint64_t tail_cache_ = 0;
    // Producer side: tail_, the producer's cached copy of head_, its counters.
    alignas(kCacheLineBytes) std::atomic<std::uint64_t> tail_{0};
    std::uint64_t head_cache_ = 0;
    std::atomic<std::uint64_t> dropped_{0};
    std::atomic<std::uint64_t> overwritten_{0};
};

}  // namespace stemd::base
