#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <vector>

#include "stemd/protocol/crc8.hpp"
#include "stemd/protocol/e2e.hpp"

using namespace stemd::protocol;

namespace {

using Payload = std::array<std::uint8_t, 8>;
constexpr std::uint16_t kDataId = 0x301;

Payload frame(std::uint8_t counter, std::uint8_t fill = 0x5A, std::uint16_t data_id = kDataId)
{
    Payload p{};
    for (std::size_t i = 1; i < p.size(); ++i)
        p[i] = static_cast<std::uint8_t>(fill + i);
    EXPECT_TRUE(e2e_protect(data_id, counter, p));
    return p;
}

}  // namespace

TEST(E2e, CrcCoversDataIdLowHighThenBytes1To7)
{
    Payload p{0x00, 0x12, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0xDE};
    const std::vector<std::uint8_t> covered{0x01, 0x03, 0x12, 0x34, 0x56, 0x78, 0x9A, 0xBC, 0xDE};
    EXPECT_EQ(e2e_crc(0x0301, p), crc8_sae_j1850(covered));
    // Byte 0 (the CRC itself) is not covered.
    Payload q = p;
    q[0] = 0xFF;
    EXPECT_EQ(e2e_crc(0x0301, q), e2e_crc(0x0301, p));
    // Both Data ID bytes are.
    EXPECT_NE(e2e_crc(0x0302, p), e2e_crc(0x0301, p));
    EXPECT_NE(e2e_crc(0x0201, p), e2e_crc(0x0301, p));
}

// Pinned values, computed independently (Python, the bitwise CRC over
// [id_lo, id_hi, bytes 1..7]): protects against layout changes.
TEST(E2e, PinnedVector)
{
    Payload p{0x00, 0x00, 0x11, 0x22, 0x33, 0x44, 0x55, 0x66};
    ASSERT_TRUE(e2e_protect(0x0300, 7, p));
    EXPECT_EQ(p[1], 0x07);
    EXPECT_EQ(p[0], 0x02);
}

TEST(E2e, ProtectWritesCounterNibbleAndKeepsHighNibble)
{
    Payload p{0x00, 0xA0, 1, 2, 3, 4, 5, 6};
    ASSERT_TRUE(e2e_protect(kDataId, 14, p));
    EXPECT_EQ(p[1], 0xAE);
    EXPECT_EQ(e2e_counter_of(p), 14);
    EXPECT_TRUE(e2e_crc_ok(kDataId, p));
    const Payload before = p;
    EXPECT_FALSE(e2e_protect(kDataId, 15, p));
    EXPECT_EQ(p, before);
}

TEST(E2e, SenderCounterWrapsAfter14)
{
    E2eCounter c;
    for (int round = 0; round < 3; ++round)
        for (int i = 0; i <= 14; ++i)
            EXPECT_EQ(c.next(), i);
    EXPECT_EQ(c.peek(), 0);
}

TEST(E2e, InOrderStreamIsInitialThenOkAcrossWrap)
{
    E2eChecker checker(kDataId);
    E2eCounter c;
    EXPECT_EQ(checker.check(frame(c.next())), E2eStatus::Initial);
    for (int i = 0; i < 40; ++i)  // wraps 14 -> 0 twice
        ASSERT_EQ(checker.check(frame(c.next(), static_cast<std::uint8_t>(i))), E2eStatus::Ok) << i;
    EXPECT_EQ(checker.count(E2eStatus::Initial), 1u);
    EXPECT_EQ(checker.count(E2eStatus::Ok), 40u);
    EXPECT_EQ(checker.accepted(), 41u);
    EXPECT_EQ(checker.rejected(), 0u);
}

TEST(E2e, InitialAcceptsAnyCounter)
{
    E2eChecker checker(kDataId);
    EXPECT_EQ(checker.check(frame(9)), E2eStatus::Initial);
    EXPECT_EQ(checker.check(frame(10)), E2eStatus::Ok);
}

TEST(E2e, WrongCrcRejectedAndStateKept)
{
    E2eChecker checker(kDataId);
    EXPECT_EQ(checker.check(frame(3)), E2eStatus::Initial);
    Payload bad = frame(4);
    bad[5] ^= 0x10;  // one flipped payload bit
    EXPECT_EQ(checker.check(bad), E2eStatus::WrongCrc);
    Payload bad_crc = frame(4);
    bad_crc[0] ^= 0x01;
    EXPECT_EQ(checker.check(bad_crc), E2eStatus::WrongCrc);
    // Another Data ID (a frame for another message, or another base).
    EXPECT_EQ(checker.check(frame(4, 0x5A, kDataId + 1)), E2eStatus::WrongCrc);
    // The state did not move: 4 is still the next expected counter.
    EXPECT_EQ(checker.check(frame(4)), E2eStatus::Ok);
    EXPECT_EQ(checker.count(E2eStatus::WrongCrc), 3u);
    EXPECT_EQ(checker.rejected(), 3u);
}

TEST(E2e, WrongCrcBeforeSyncIsNotInitial)
{
    E2eChecker checker(kDataId);
    Payload bad = frame(0);
    bad[7] ^= 0x80;
    EXPECT_EQ(checker.check(bad), E2eStatus::WrongCrc);
    EXPECT_EQ(checker.check(frame(5)), E2eStatus::Initial);
}

TEST(E2e, RepeatedRejected)
{
    E2eChecker checker(kDataId);
    EXPECT_EQ(checker.check(frame(14)), E2eStatus::Initial);
    EXPECT_EQ(checker.check(frame(14)), E2eStatus::Repeated);
    EXPECT_EQ(checker.check(frame(0)), E2eStatus::Ok);
    EXPECT_EQ(checker.count(E2eStatus::Repeated), 1u);
}

TEST(E2e, JumpRejectedThenResyncs)
{
    E2eChecker checker(kDataId);  // max delta 1: no loss tolerated
    EXPECT_EQ(checker.check(frame(1)), E2eStatus::Initial);
    EXPECT_EQ(checker.check(frame(3)), E2eStatus::WrongSequence);  // one frame lost
    EXPECT_EQ(checker.check(frame(4)), E2eStatus::Ok);             // resynchronised on 3
    // A jump across the wrap: 13 -> 1 is delta 3.
    EXPECT_EQ(checker.check(frame(13)), E2eStatus::WrongSequence);
    EXPECT_EQ(checker.check(frame(1)), E2eStatus::WrongSequence);
    EXPECT_EQ(checker.check(frame(2)), E2eStatus::Ok);
    // Going backwards is a large forward delta.
    EXPECT_EQ(checker.check(frame(1)), E2eStatus::WrongSequence);
    EXPECT_EQ(checker.count(E2eStatus::WrongSequence), 4u);
    EXPECT_EQ(checker.lost(), 0u);
}

TEST(E2e, MaxDeltaCounterToleratesSomeLoss)
{
    E2eChecker checker(kDataId, 3);
    EXPECT_EQ(checker.max_delta_counter(), 3);
    EXPECT_EQ(checker.check(frame(12)), E2eStatus::Initial);
    EXPECT_EQ(checker.check(frame(14)), E2eStatus::OkSomeLost);  // delta 2
    EXPECT_EQ(checker.check(frame(2)), E2eStatus::OkSomeLost);   // 14 -> 2 across the wrap: delta 3
    EXPECT_EQ(checker.check(frame(6)), E2eStatus::WrongSequence);  // delta 4
    EXPECT_EQ(checker.check(frame(7)), E2eStatus::Ok);
    EXPECT_EQ(checker.lost(), 1u + 2u);
    EXPECT_EQ(checker.count(E2eStatus::OkSomeLost), 2u);
}

TEST(E2e, MaxDeltaCounterIsClamped)
{
    EXPECT_EQ(E2eChecker(kDataId, 0).max_delta_counter(), 1);
    EXPECT_EQ(E2eChecker(kDataId, 200).max_delta_counter(), 14);
    // With 14, every counter but the same one is accepted.
    E2eChecker checker(kDataId, 14);
    EXPECT_EQ(checker.check(frame(5)), E2eStatus::Initial);
    EXPECT_EQ(checker.check(frame(4)), E2eStatus::OkSomeLost);  // delta 14
    EXPECT_EQ(checker.check(frame(4)), E2eStatus::Repeated);
}

TEST(E2e, Counter15IsAWrongSequenceAndKeepsState)
{
    E2eChecker checker(kDataId, 14);
    EXPECT_EQ(checker.check(frame(6)), E2eStatus::Initial);
    Payload p = frame(0);
    p[1] = static_cast<std::uint8_t>((p[1] & 0xF0) | 0x0F);
    p[0] = e2e_crc(kDataId, p);  // valid CRC, invalid counter
    EXPECT_EQ(checker.check(p), E2eStatus::WrongSequence);
    EXPECT_EQ(checker.check(frame(7)), E2eStatus::Ok);
}

TEST(E2e, ResetMakesNextFrameInitial)
{
    E2eChecker checker(kDataId);
    EXPECT_EQ(checker.check(frame(0)), E2eStatus::Initial);
    checker.reset();
    EXPECT_EQ(checker.check(frame(9)), E2eStatus::Initial);
    EXPECT_EQ(checker.count(E2eStatus::Initial), 2u);
}

TEST(E2e, StatusNames)
{
    EXPECT_EQ(to_string(E2eStatus::WrongCrc), "wrong_crc");
    EXPECT_EQ(to_string(E2eStatus::OkSomeLost), "ok_some_lost");
    EXPECT_TRUE(e2e_accepted(E2eStatus::Initial));
    EXPECT_FALSE(e2e_accepted(E2eStatus::Repeated));
}
