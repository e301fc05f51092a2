#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <random>

#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"

using namespace stemd::protocol;

namespace {

const CanIds kIds;  // default base 0x300

template <typename Msg>
Msg round_trip(const Msg& in, std::uint8_t counter = 0, const CanIds& ids = kIds)
{
    CanFrame f;
    const CodecResult enc = encode(in, counter, ids, f);
    EXPECT_TRUE(enc) << to_string(enc.error) << " " << enc.signal;
    EXPECT_EQ(f.dlc, 8);
    EXPECT_FALSE(f.extended);
    EXPECT_EQ(e2e_counter_of(f.data), counter);
    Msg out{};
    const CodecResult dec = decode(f, ids, out);
    EXPECT_TRUE(dec) << to_string(dec.error) << " " << dec.signal;
    return out;
}

// Encoding must fail with OutOfRange naming `signal`, leaving the frame alone.
template <typename Msg>
void expect_rejected(const Msg& in, std::string_view signal)
{
    CanFrame f;
    f.id = 0x123;
    const CanFrame before = f;
    const CodecResult r = encode(in, 0, kIds, f);
    EXPECT_EQ(r.error, CodecError::OutOfRange) << signal;
    EXPECT_EQ(r.signal, signal);
    EXPECT_EQ(f, before);
}

// Rewrites bits of an encoded frame and re-protects it, so that only the
// range check can catch it.
CanFrame with_bits(CanFrame f, unsigned start, unsigned length, std::uint64_t raw)
{
    std::uint64_t w = 0;
    for (std::size_t i = 0; i < 8; ++i)
        w |= std::uint64_t{f.data[i]} << (8 * i);
    const std::uint64_t mask = ((std::uint64_t{1} << length) - 1) << start;
    w = (w & ~mask) | ((raw << start) & mask);
    for (std::size_t i = 0; i < 8; ++i)
        f.data[i] = static_cast<std::uint8_t>(w >> (8 * i));
    e2e_protect(static_cast<std::uint16_t>(f.id), e2e_counter_of(f.data), f.data);
    return f;
}

}  // namespace

TEST(CanIds, DefaultBaseAndOffsets)
{
    EXPECT_EQ(kIds.base(), 0x300);
    EXPECT_EQ(kIds.id(MessageKind::Odometry), 0x300);
    EXPECT_EQ(kIds.id(MessageKind::Target), 0x301);
    EXPECT_EQ(kIds.id(MessageKind::ToolStatus), 0x302);
    EXPECT_EQ(kIds.id(MessageKind::Heartbeat), 0x303);
    EXPECT_EQ(kIds.id(MessageKind::ToolFired), 0x304);
    for (MessageKind k : kAllMessageKinds)
        EXPECT_EQ(kIds.id(k), kIds.base() + message_def(k).id_offset);
}

TEST(CanIds, ConfigurableBaseStaysElevenBit)
{
    ASSERT_TRUE(CanIds::make(0x000));
    ASSERT_TRUE(CanIds::make(0x7FB));
    EXPECT_EQ(CanIds::make(0x7FB)->id(MessageKind::ToolFired), 0x7FF);
    EXPECT_FALSE(CanIds::make(0x7FC));
    EXPECT_FALSE(CanIds::make(0x800));
    EXPECT_FALSE(CanIds::make(0xFFFFFFFF));
}

TEST(CanIds, KindOf)
{
    const CanIds ids = *CanIds::make(0x120);
    CanFrame f;
    f.id = 0x122;
    EXPECT_EQ(ids.kind_of(f), MessageKind::ToolStatus);
    f.id = 0x11F;
    EXPECT_FALSE(ids.kind_of(f));
    f.id = 0x124;
    EXPECT_EQ(ids.kind_of(f), MessageKind::ToolFired);
    f.id = 0x125;
    EXPECT_FALSE(ids.kind_of(f));
    f.id = 0x120;
    f.extended = true;
    EXPECT_FALSE(ids.kind_of(f));
}

TEST(Messages, TargetPinnedFrame)
{
    const TargetCommand t{0xABC, 5, 9, 0x12345, -100, PlantClass::Weed};
    CanFrame f;
    ASSERT_TRUE(encode(t, 3, kIds, f));
    EXPECT_EQ(f.id, 0x301u);
    // Computed independently (Python: bit layout + bitwise CRC-8 over 01 03 + bytes 1..7).
    const std::array<std::uint8_t, 8> expected{0xD3, 0x53, 0xBC, 0x9A, 0x45, 0x23, 0x71, 0xBE};
    EXPECT_EQ(f.data, expected);
}

TEST(Messages, TargetRoundTripAtLimits)
{
    const TargetCommand lo{0, 0, 0, 0, -kMaxLateralMm, PlantClass::Unknown};
    const TargetCommand hi{kMaxTargetId, kMaxToolId, kMaxLane, kFireOdomModulo - 1, kMaxLateralMm, PlantClass::Weed};
    const TargetCommand mid{1234, 7, 3, 100000, -1, PlantClass::Crop};
    EXPECT_EQ(round_trip(lo, 0), lo);
    EXPECT_EQ(round_trip(hi, 14), hi);
    EXPECT_EQ(round_trip(mid, 7), mid);
}

TEST(Messages, TargetFireOdomIsSentModulo2To18)
{
    TargetCommand t{1, 1, 1, 0, 0, PlantClass::Weed};
    for (std::uint32_t odom : {0u, 262143u, 262144u, 1000000u, 0xFFFFFFFFu}) {
        t.fire_odom_mm = odom;
        EXPECT_EQ(round_trip(t).fire_odom_mm, odom % kFireOdomModulo) << odom;
    }
}

TEST(Messages, FireDistanceIsWrapSafe)
{
    EXPECT_EQ(fire_distance_mm(1500, 1000), 500);
    EXPECT_EQ(fire_distance_mm(1000, 1500), -500);
    // Across the 2^18 wrap of the field: fire at odometer 262144 + 100, sent as 100.
    EXPECT_EQ(fire_distance_mm(100, 262100), 144);
    EXPECT_EQ(fire_distance_mm(262100, 100), -144);
    // The full 32-bit odometer may be passed as it is, even across its own wrap.
    const std::uint32_t odom = 0xFFFFFF00u;
    const std::uint32_t fire = odom + 0x200;  // wrapped to 0x100
    EXPECT_EQ(fire_distance_mm(fire % kFireOdomModulo, odom), 0x200);
    EXPECT_EQ(fire_distance_mm(fire, odom), 0x200);
    // The half-range limit.
    EXPECT_EQ(fire_distance_mm(131071, 0), 131071);
    EXPECT_EQ(fire_distance_mm(131072, 0), -131072);
}

TEST(Messages, TargetRejectsOutOfRange)
{
    const TargetCommand ok{1, 1, 1, 1, 1, PlantClass::Weed};
    TargetCommand t = ok;
    t.target_id = kMaxTargetId + 1;
    expect_rejected(t, "target_id");
    t = ok;
    t.tool_id = 16;
    expect_rejected(t, "tool_id");
    t = ok;
    t.lane = 16;
    expect_rejected(t, "lane");
    t = ok;
    t.lateral_mm = 2048;
    expect_rejected(t, "lateral_mm");
    t.lateral_mm = -2048;
    expect_rejected(t, "lateral_mm");
    t.lateral_mm = std::numeric_limits<std::int16_t>::min();
    expect_rejected(t, "lateral_mm");
    t = ok;
    t.plant_class = static_cast<PlantClass>(3);
    expect_rejected(t, "plant_class");
    // The first offending signal in layout order is named.
    t = ok;
    t.lane = 99;
    t.tool_id = 99;
    expect_rejected(t, "tool_id");
}

TEST(Messages, BadCounterRejected)
{
    CanFrame f;
    const CanFrame before = f;
    const CodecResult r = encode(TargetCommand{}, 15, kIds, f);
    EXPECT_EQ(r.error, CodecError::BadCounter);
    EXPECT_EQ(f, before);
    EXPECT_EQ(encode(Heartbeat{}, 255, kIds, f).error, CodecError::BadCounter);
}

TEST(Messages, OdometryRoundTripAtLimits)
{
    EXPECT_EQ(round_trip(Odometry{0, 0}), (Odometry{0, 0}));
    EXPECT_EQ(round_trip(Odometry{0xFFFFFFFFu, kMaxSpeedMmPerS}, 14), (Odometry{0xFFFFFFFFu, kMaxSpeedMmPerS}));
    EXPECT_EQ(round_trip(Odometry{123456789, -kMaxSpeedMmPerS}), (Odometry{123456789, -kMaxSpeedMmPerS}));
    expect_rejected(Odometry{0, std::numeric_limits<std::int16_t>::min()}, "speed_mm_per_s");
}

TEST(Messages, ToolStatusRoundTripAtLimits)
{
    const ToolStatus lo{};
    const ToolStatus hi{0xFFFF, kMaxTargetId, true, 255, 255};
    const ToolStatus mid{0x8001, 77, true, tool_error::kTargetLate, 3};
    EXPECT_EQ(round_trip(lo), lo);
    EXPECT_EQ(round_trip(hi, 14), hi);
    EXPECT_EQ(round_trip(mid, 1), mid);
    expect_rejected(ToolStatus{0, kMaxTargetId + 1, true, 0, 0}, "last_target_id");
}

TEST(Messages, HeartbeatRoundTripAndCounterPolicy)
{
    const Heartbeat hb{DaemonState::Degraded, 65535, 4095, 4095, 255};
    EXPECT_EQ(round_trip(hb, 14), hb);
    // targets_sent wraps; the error counters saturate.
    const Heartbeat big{DaemonState::Active, 65536 + 17, 5000, std::numeric_limits<std::uint64_t>::max(), 256};
    const Heartbeat got = round_trip(big);
    EXPECT_EQ(got.state, DaemonState::Active);
    EXPECT_EQ(got.targets_sent, 17u);
    EXPECT_EQ(got.deadline_misses, 4095u);
    EXPECT_EQ(got.targets_dropped, 4095u);
    EXPECT_EQ(got.rx_rejected, 255u);
    for (int s = 0; s <= 5; ++s)
        EXPECT_EQ(round_trip(Heartbeat{static_cast<DaemonState>(s), 0, 0, 0, 0}).state, static_cast<DaemonState>(s));
    EXPECT_EQ(static_cast<int>(DaemonState::CameraLost), 5);
    Heartbeat bad{};
    bad.state = static_cast<DaemonState>(6);
    expect_rejected(bad, "state");
}

TEST(Messages, DecodeChecksIdLengthAndCrc)
{
    const TargetCommand t{42, 2, 3, 4000, -7, PlantClass::Weed};
    CanFrame f;
    ASSERT_TRUE(encode(t, 5, kIds, f));
    TargetCommand out{};
    const TargetCommand untouched = out;

    CanFrame g = f;
    g.id = kIds.id(MessageKind::Heartbeat);
    EXPECT_EQ(decode(g, kIds, out).error, CodecError::WrongId);
    g = f;
    g.extended = true;
    EXPECT_EQ(decode(g, kIds, out).error, CodecError::WrongId);
    g = f;
    g.dlc = 7;
    EXPECT_EQ(decode(g, kIds, out).error, CodecError::WrongLength);
    g = f;
    g.data[4] ^= 0x01;
    EXPECT_EQ(decode(g, kIds, out).error, CodecError::WrongCrc);
    // Another base: the same bytes under another identifier fail the CRC,
    // because the Data ID is the identifier.
    const CanIds other = *CanIds::make(0x400);
    g = f;
    g.id = other.id(MessageKind::Target);
    EXPECT_EQ(decode(g, other, out).error, CodecError::WrongCrc);
    EXPECT_EQ(out, untouched);

    EXPECT_TRUE(decode(f, kIds, out));
    EXPECT_EQ(out, t);
}

TEST(Messages, WorksWithAnyBase)
{
    const CanIds ids = *CanIds::make(0x7FB);
    const TargetCommand t{4095, 15, 15, 5, 5, PlantClass::Crop};
    EXPECT_EQ(round_trip(t, 9, ids), t);
    CanFrame f;
    ASSERT_TRUE(encode(ToolFired{}, 0, ids, f));
    EXPECT_EQ(f.id, 0x7FFu);
}

TEST(Messages, DecodeRejectsOutOfRangeFieldsWithValidCrc)
{
    CanFrame f;
    ASSERT_TRUE(encode(TargetCommand{1, 1, 1, 1, 1, PlantClass::Weed}, 0, kIds, f));
    TargetCommand t{};
    CodecResult r = decode(with_bits(f, 62, 2, 3), kIds, t);  // plant_class 3
    EXPECT_EQ(r.error, CodecError::OutOfRange);
    EXPECT_EQ(r.signal, "plant_class");
    r = decode(with_bits(f, 50, 12, 0x800), kIds, t);  // lateral_mm -2048
    EXPECT_EQ(r.signal, "lateral_mm");

    ASSERT_TRUE(encode(Heartbeat{}, 0, kIds, f));
    Heartbeat hb{};
    EXPECT_EQ(decode(with_bits(f, 12, 4, 9), kIds, hb).signal, "state");

    ASSERT_TRUE(encode(Odometry{}, 0, kIds, f));
    Odometry od{};
    EXPECT_EQ(decode(with_bits(f, 48, 16, 0x8000), kIds, od).signal, "speed_mm_per_s");
}

TEST(Messages, ReservedBitsAreZeroAndIgnored)
{
    CanFrame f;
    ASSERT_TRUE(encode(ToolStatus{0xFFFF, kMaxTargetId, true, 255, 255}, 0, kIds, f));
    EXPECT_EQ(f.data[1] & 0xF0, 0);  // bits 12..15
    EXPECT_EQ(f.data[5] & 0xE0, 0);  // bits 45..47
    ToolStatus s{};
    ASSERT_TRUE(decode(with_bits(f, 45, 3, 7), kIds, s));
    EXPECT_EQ(s, (ToolStatus{0xFFFF, kMaxTargetId, true, 255, 255}));

    ASSERT_TRUE(encode(Odometry{0xFFFFFFFFu, -1}, 0, kIds, f));
    EXPECT_EQ(f.data[1] & 0xF0, 0);
}

TEST(Messages, RandomRoundTrips)
{
    std::mt19937 rng(2024);
    E2eCounter counter;
    for (int i = 0; i < 2000; ++i) {
        TargetCommand t;
        t.target_id = static_cast<std::uint16_t>(rng() % 4096);
        t.tool_id = static_cast<std::uint8_t>(rng() % 16);
        t.lane = static_cast<std::uint8_t>(rng() % 16);
        t.fire_odom_mm = static_cast<std::uint32_t>(rng() % kFireOdomModulo);
        t.lateral_mm = static_cast<std::int16_t>(static_cast<int>(rng() % 4095) - 2047);
        t.plant_class = static_cast<PlantClass>(rng() % 3);
        ASSERT_EQ(round_trip(t, counter.next()), t);
        Odometry o{static_cast<std::uint32_t>(rng()), static_cast<std::int16_t>(static_cast<int>(rng() % 65535) - 32767)};
        ASSERT_EQ(round_trip(o, counter.next()), o);
    }
}

TEST(Messages, ToolFiredPinnedFrameSharesTheTargetsBits)
{
    const ToolFired fired{0xABC, 5, 9, 0x12345};
    CanFrame f;
    ASSERT_TRUE(encode(fired, 3, kIds, f));
    EXPECT_EQ(f.id, 0x304u);
    // Computed independently (Python: bit layout + bitwise CRC-8 over 04 03 + bytes 1..7).
    const std::array<std::uint8_t, 8> expected{0xDE, 0x53, 0xBC, 0x9A, 0x45, 0x23, 0x01, 0x00};
    EXPECT_EQ(f.data, expected);
    // tool_id, target_id, lane and the odometer sit where the TARGET has them.
    CanFrame t;
    ASSERT_TRUE(encode(TargetCommand{0xABC, 5, 9, 0x12345, 0, PlantClass::Unknown}, 3, kIds, t));
    for (std::size_t i = 1; i < 6; ++i)
        EXPECT_EQ(f.data[i], t.data[i]) << "byte " << i;
    EXPECT_EQ(f.data[6] & 0x03, t.data[6] & 0x03);
}

TEST(Messages, ToolFiredRoundTripWrapsAndRejects)
{
    EXPECT_EQ(round_trip(ToolFired{}), ToolFired{});
    const ToolFired hi{kMaxTargetId, kMaxToolId, kMaxLane, kFireOdomModulo - 1};
    EXPECT_EQ(round_trip(hi, 14), hi);
    // Any odometer reading goes out modulo 2^18, as fire_odom_mm does.
    EXPECT_EQ(round_trip(ToolFired{1, 2, 3, 0xFFFFFFFFu}).fired_odom_mm, kFireOdomModulo - 1);
    EXPECT_EQ(round_trip(ToolFired{1, 2, 3, kFireOdomModulo + 17}).fired_odom_mm, 17u);

    CanFrame f;
    EXPECT_EQ(encode(ToolFired{1, 16, 0, 0}, 0, kIds, f).signal, "tool_id");
    EXPECT_EQ(encode(ToolFired{4096, 0, 0, 0}, 0, kIds, f).signal, "target_id");
    ASSERT_TRUE(encode(ToolFired{7, 1, 0, 1000}, 0, kIds, f));
    // Reserved bits 50..63 are sent as 0.
    EXPECT_EQ(f.data[6] & 0xFC, 0);
    EXPECT_EQ(f.data[7], 0);
    ToolFired out{};
    CanFrame bad = f;
    bad.data[4] ^= 0x01;  // one odometer bit flipped: the CRC no longer holds
    EXPECT_EQ(decode(bad, kIds, out).error, CodecError::WrongCrc);
    EXPECT_EQ(out, ToolFired{});
    CanFrame other = f;
    other.id = kIds.id(MessageKind::ToolStatus);
    EXPECT_EQ(decode(other, kIds, out).error, CodecError::WrongId);
}

TEST(Messages, Names)
{
    EXPECT_EQ(to_string(MessageKind::ToolFired), "TOOL_FIRED");
    EXPECT_EQ(to_string(MessageKind::ToolStatus), "TOOL_STATUS");
    EXPECT_EQ(to_string(CodecError::WrongCrc), "wrong CRC");
}

TEST(Messages, ToolErrorCodesAreNamedAsInTheDbc)
{
    EXPECT_EQ(tool_error_name(tool_error::kNone), "NONE");
    EXPECT_EQ(tool_error_name(tool_error::kNotReady), "NOT_READY");
    EXPECT_EQ(tool_error_name(tool_error::kActuatorFault), "ACTUATOR_FAULT");
    EXPECT_EQ(tool_error_name(tool_error::kOther), "OTHER");
    EXPECT_EQ(tool_error_name(77), "");
}
