#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string_view>
#include <vector>

#include "stemd/protocol/crc8.hpp"

using stemd::protocol::crc8_sae_j1850;

namespace {

std::uint8_t crc(std::vector<std::uint8_t> bytes) { return crc8_sae_j1850(bytes); }

// Bit-by-bit reference: poly 0x1D, init 0xFF, no reflection, xor-out 0xFF.
std::uint8_t reference(const std::vector<std::uint8_t>& bytes)
{
    std::uint8_t c = 0xFF;
    for (std::uint8_t b : bytes) {
        c ^= b;
        for (int i = 0; i < 8; ++i)
            c = static_cast<std::uint8_t>((c & 0x80) ? (c << 1) ^ 0x1D : c << 1);
    }
    return static_cast<std::uint8_t>(c ^ 0xFF);
}

}  // namespace

TEST(Crc8, CheckValue)
{
    constexpr std::string_view kCheck = "123456789";
    std::vector<std::uint8_t> bytes(kCheck.begin(), kCheck.end());
    EXPECT_EQ(crc(bytes), 0x4B);
}

// AUTOSAR SWS CRC Library, Crc_CalculateCRC8 (SAE J1850) check values.
TEST(Crc8, AutosarVectors)
{
    EXPECT_EQ(crc({0x00, 0x00, 0x00, 0x00}), 0x59);
    EXPECT_EQ(crc({0xF2, 0x01, 0x83}), 0x37);
    EXPECT_EQ(crc({0x0F, 0xAA, 0x00, 0x55}), 0x79);
    EXPECT_EQ(crc({0x00, 0xFF, 0x55, 0x11}), 0xB8);
    EXPECT_EQ(crc({0x33, 0x22, 0x55, 0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0xFF}), 0xCB);
    EXPECT_EQ(crc({0x92, 0x6B, 0x55}), 0x8C);
    EXPECT_EQ(crc({0xFF, 0xFF, 0xFF, 0xFF}), 0x74);
}

TEST(Crc8, EmptyInputIsInitXorOut)
{
    EXPECT_EQ(crc({}), 0x00);  // 0xFF ^ 0xFF
}

TEST(Crc8, ChainedCallsEqualOneCall)
{
    const std::vector<std::uint8_t> all{0x33, 0x22, 0x55, 0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0xFF};
    for (std::size_t split = 0; split <= all.size(); ++split) {
        const std::span<const std::uint8_t> a(all.data(), split);
        const std::span<const std::uint8_t> b(all.data() + split, all.size() - split);
        const std::uint8_t first = crc8_sae_j1850(a);
        EXPECT_EQ(crc8_sae_j1850(b, first, false), 0xCB) << "split at " << split;
    }
    // The start value is ignored on a first call.
    EXPECT_EQ(crc8_sae_j1850(all, 0x12, true), 0xCB);
}

TEST(Crc8, TableEqualsBitwiseReference)
{
    std::mt19937 rng(7);
    for (int n = 0; n < 500; ++n) {
        std::vector<std::uint8_t> bytes(static_cast<std::size_t>(rng() % 20));
        for (auto& b : bytes)
            b = static_cast<std::uint8_t>(rng());
        ASSERT_EQ(crc(bytes), reference(bytes));
    }
}
