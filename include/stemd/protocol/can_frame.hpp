// A classic CAN 2.0 frame (at most 8 data bytes), as the CAN buses send and
// receive it and candump logs hold it. Header-only: a plain value type.
#pragma once

#include <array>
#include <cstdint>

namespace stemd::protocol {

inline constexpr std::uint32_t kMaxStandardId = 0x7FF;       // 11-bit identifier
inline constexpr std::uint32_t kMaxExtendedId = 0x1FFFFFFF;  // 29-bit identifier

struct CanFrame {
    std::uint32_t id = 0;       // the identifier, without flag bits
    bool extended = false;      // 29-bit identifier (all of stemd's own messages are 11-bit)
    std::uint8_t dlc = 0;       // number of data bytes, 0..8
    std::array<std::uint8_t, 8> data{};  // bytes past dlc are zero

    friend bool operator==(const CanFrame&, const CanFrame&) = default;
};

}  // namespace stemd::protocol
