#include "stemd/protocol/crc8.hpp"

#include <array>

namespace stemd::protocol {

namespace {

constexpr std::uint8_t kPoly = 0x1D;
constexpr std::uint8_t kInit = 0xFF;
constexpr std::uint8_t kXorOut = 0xFF;

constexpr std::array<std::uint8_t, 256> make_table()
{
    std::array<std::uint8_t, 256> table{};
    for (int i = 0; i < 256; ++i) {
        auto crc = static_cast<std::uint8_t>(i);
        for (int bit = 0; bit < 8; ++bit)
            crc = static_cast<std::uint8_t>((crc & 0x80) ? (crc << 1) ^ kPoly : crc << 1);
        table[static_cast<std::size_t>(i)] = crc;
    }
    return table;
}

constexpr auto kTable = make_table();

constexpr std::uint8_t update(std::uint8_t crc, std::span<const std::uint8_t> data)
{
    for (std::uint8_t byte : data)
        crc = kTable[static_cast<std::uint8_t>(crc ^ byte)];
    return crc;
}

constexpr std::uint8_t crc_of(std::span<const std::uint8_t> data)
{
    return static_cast<std::uint8_t>(update(kInit, data) ^ kXorOut);
}

constexpr std::array<std::uint8_t, 9> kCheckInput{'1', '2', '3', '4', '5', '6', '7', '8', '9'};
static_assert(crc_of(kCheckInput) == 0x4B, "CRC-8 SAE J1850 check value");

}  // namespace

std::uint8_t crc8_sae_j1850(std::span<const std::uint8_t> data, std::uint8_t start_value, bool is_first_call)
{
    const std::uint8_t crc = is_first_call ? kInit : static_cast<std::uint8_t>(start_value ^ kXorOut);
    return static_cast<std::uint8_t>(update(crc, data) ^ kXorOut);
}

}  // namespace stemd::protocol
