#include "stemd/runtime/class_slots.hpp"

#include <algorithm>
#include <cstring>

namespace stemd::runtime {

ClassSlotTable::ClassSlotTable(std::size_t slots, std::size_t max_bytes)
    : slots_(std::max<std::size_t>(slots, 2)), max_bytes_(max_bytes)
{
    for (Slot& s : slots_)
        s.classes = std::make_unique<std::uint8_t[]>(max_bytes);
}

bool ClassSlotTable::store(std::int64_t t_capture_ns, int width, int height, const std::uint8_t* classes,
                           std::int64_t received_ns) noexcept
{
    if (width <= 0 || height <= 0 || static_cast<std::size_t>(width) * static_cast<std::size_t>(height) > max_bytes_)
        return false;
    // The slot to take: the same frame's, else a free one, else the oldest
    // frame's; one the reader holds is passed over (it holds at most one).
    for (;;) {
        Slot* same = nullptr;
        Slot* free = nullptr;
        Slot* oldest = nullptr;
        for (Slot& s : slots_) {
            const std::uint8_t state = s.state.load(std::memory_order_acquire);
            const std::int64_t t = s.t_capture_ns.load(std::memory_order_relaxed);
            if (state == kFree && free == nullptr)
                free = &s;
            else if (state == kReady && t == t_capture_ns)
                same = &s;
            else if (state == kReady && (oldest == nullptr || t < oldest->t_capture_ns.load(std::memory_order_relaxed)))
                oldest = &s;
        }
        Slot* const pick = same != nullptr ? same : free != nullptr ? free : oldest;
        if (pick == nullptr)
            return false;   // cannot happen with >= 2 slots and one reader
        std::uint8_t expected = pick->state.load(std::memory_order_relaxed);
        if (expected == kReading || expected == kWriting ||
            !pick->state.compare_exchange_strong(expected, kWriting, std::memory_order_acquire))
            continue;   // the reader took it meanwhile: choose again
        pick->t_capture_ns.store(kNoFrame, std::memory_order_relaxed);
        pick->width = width;
        pick->height = height;
        pick->received_ns = received_ns;
        std::memcpy(pick->classes.get(), classes, static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
        pick->t_capture_ns.store(t_capture_ns, std::memory_order_relaxed);
        pick->state.store(kReady, std::memory_order_release);
        return true;
    }
}

}  // namespace stemd::runtime
