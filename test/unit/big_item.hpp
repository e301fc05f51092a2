// An item too large to copy for free, numbered, as the rings and buffers
// carry them (like FrameResult): stress tests check each arrives whole.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace stemd::test {

template <std::size_t N>
struct BigItem {
    std::uint64_t seq = 0;
    std::array<std::uint64_t, N> payload{};
};

}  // namespace stemd::test
