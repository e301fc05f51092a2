// CRC-8 SAE J1850, as AUTOSAR's Crc_CalculateCRC8 and E2E profiles 1/11 use it:
// polynomial 0x1D, initial value 0xFF, final XOR 0xFF, no reflection.
// Check value: "123456789" -> 0x4B.
#pragma once

#include <cstdint>
#include <span>

namespace stemd::protocol {

// Same contract as AUTOSAR Crc_CalculateCRC8(data, length, start_value, is_first_call):
// - is_first_call: start from 0xFF and ignore start_value;
// - otherwise start_value is the result of the previous call on the preceding
//   bytes, so that chained calls equal one call over the concatenated data.
// Table-driven (a 256-byte table built at compile time); allocation-free.
std::uint8_t crc8_sae_j1850(std::span<const std::uint8_t> data, std::uint8_t start_value = 0,
                            bool is_first_call = true);

}  // namespace stemd::protocol
