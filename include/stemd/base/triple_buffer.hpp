// A triple buffer: one writer thread hands the latest value to one reader
// thread, and neither ever waits for the other. Three slots, allocated at
// construction; then the writer fills its own slot and publishes it (an
// atomic exchange with the middle slot), and the reader takes the middle
// slot when it is fresh (another exchange). The reader always sees the most
// recent publication whole; publications it did not take are overwritten,
// which is what a live view wants (the newest frame, never a queue).
//
//   writer: T& w = buffer.write_slot(); fill w; buffer.publish();
//   reader: if (buffer.take()) use(buffer.read_slot());
//
// The middle index and its "fresh" bit share one atomic byte; the exchanges
// are acq_rel, so the writes into a slot happen-before the reads of whoever
// takes it. Nothing allocates after construction, nothing locks.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>

namespace stemd::base {

template <class T>
class TripleBuffer {
public:
    // Three default-constructed slots, each then given to init (e.g. to
    // allocate an image of the frame size): the only allocations.
    template <class Init>
    explicit TripleBuffer(Init&& init) : slots_(new T[3]())
    {
        for (int i = 0; i < 3; ++i)
            init(slots_[i]);
    }
    TripleBuffer() : TripleBuffer([](T&) {}) {}
    TripleBuffer(const TripleBuffer&) = delete;
    TripleBuffer& operator=(const TripleBuffer&) = delete;

    // --- writer ---------------------------------------------------------------
    // The slot the writer owns: the reader never sees it until publish().
    T& write_slot() { return slots_[write_]; }
    // Makes the write slot the newest publication and takes back the middle
    // slot (an older, untaken publication, or one the reader returned).
    void publish()
    {
        const std::uint8_t old = middle_.exchange(static_cast<std::uint8_t>(write_ | kFresh), std::memory_order_acq_rel);
        write_ = old & kIndex;
        published_.store(published_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    }

    // --- reader ---------------------------------------------------------------
    // Takes the newest publication if there is one the reader has not taken
    // yet (true); read_slot() is then it. False: read_slot() is unchanged.
    bool take()
    {
        if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0)
            return false;
        const std::uint8_t old = middle_.exchange(read_, std::memory_order_acq_rel);
        read_ = old & kIndex;
        return true;
    }
    // The slot last taken (a default slot before the first take()).
    const T& read_slot() const { return slots_[read_]; }

    // Publications so far; any thread (relaxed, for counters).
    std::uint64_t published() const { return published_.load(std::memory_order_relaxed); }

private:
    static constexpr std::uint8_t kIndex = 0x3;
    static constexpr std::uint8_t kFresh = 0x4;

    std::unique_ptr<T[]> slots_;
    std::uint8_t write_ = 0;                 // the writer's
    std::atomic<std::uint8_t> middle_{1};    // shared: index | kFresh
    std::uint8_t read_ = 2;                  // the reader's
    std::atomic<std::uint64_t> published_{0};
};

}  // namespace stemd::base
