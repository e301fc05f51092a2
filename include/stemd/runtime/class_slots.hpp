// Class maps from an external provider, keyed by their frame's
// t_capture_ns: one writer (the socket's receiver thread) stores them in
// slots allocated at start, one reader (the actuator thread) takes the one
// its frame needs. Neither locks nor allocates: each slot's state is an
// atomic that hands the slot to one side at a time, so a map is never read
// while it is being written.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace stemd::runtime {

class ClassSlotTable {
public:
    // `slots` maps of at most max_bytes each (>= 2 slots: the reader may hold one).
    ClassSlotTable(std::size_t slots, std::size_t max_bytes);

    // Writer: a copy of the map, received at received_ns, into a free slot or
    // else the one holding the oldest frame. False when it is larger than a
    // slot. A second map for the same frame replaces the first.
    bool store(std::int64_t t_capture_ns, int width, int height, const std::uint8_t* classes,
               std::int64_t received_ns) noexcept;

    enum class Lookup : std::uint8_t {
        hit,       // read() was called with the map; the slot is free again
        miss,      // not there, and the deadline has not passed: ask again
        expired,   // not there by the deadline, or it came after it
    };
    // Reader: the map of the frame taken at t_capture_ns, if it was received
    // by deadline_ns. read(const cv::Mat&) gets a CV_8UC1 view of the slot
    // (no copy) and runs before the slot is given back.
    template <class Read>
    Lookup lookup(std::int64_t t_capture_ns, std::int64_t now_ns, std::int64_t deadline_ns, Read&& read) noexcept
    {
        for (Slot& s : slots_) {
            std::uint8_t expected = kReady;
            if (s.t_capture_ns.load(std::memory_order_acquire) != t_capture_ns ||
                !s.state.compare_exchange_strong(expected, kReading, std::memory_order_acquire))
                continue;
            if (s.t_capture_ns.load(std::memory_order_relaxed) != t_capture_ns) {   // replaced meanwhile
                s.state.store(kReady, std::memory_order_release);
                continue;
            }
            const bool in_time = s.received_ns <= deadline_ns;
            if (in_time)
                read(cv::Mat(s.height, s.width, CV_8UC1, s.classes.get()));
            s.t_capture_ns.store(kNoFrame, std::memory_order_relaxed);
            s.state.store(kFree, std::memory_order_release);
            return in_time ? Lookup::hit : Lookup::expired;
        }
        return now_ns < deadline_ns ? Lookup::miss : Lookup::expired;
    }

    std::size_t slots() const { return slots_.size(); }
    std::size_t max_bytes() const { return max_bytes_; }

private:
    static constexpr std::uint8_t kFree = 0, kWriting = 1, kReady = 2, kReading = 3;
    static constexpr std::int64_t kNoFrame = INT64_MIN;
    struct Slot {
        std::atomic<std::uint8_t> state{kFree};
        std::atomic<std::int64_t> t_capture_ns{kNoFrame};
        // Written only in kWriting, read only in kReading.
        std::int64_t received_ns = 0;
        int width = 0, height = 0;
        std::unique_ptr<std::uint8_t[]> classes;
    };
    std::vector<Slot> slots_;
    std::size_t max_bytes_;
};

}  // namespace stemd::runtime
