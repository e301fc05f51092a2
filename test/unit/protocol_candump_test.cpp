#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include "stemd/protocol/candump_format.hpp"
#include "stemd/protocol/messages.hpp"

using namespace stemd::protocol;

namespace {

CanFrame frame(std::uint32_t id, std::initializer_list<std::uint8_t> bytes, bool extended = false)
{
    CanFrame f;
    f.id = id;
    f.extended = extended;
    f.dlc = static_cast<std::uint8_t>(bytes.size());
    std::size_t i = 0;
    for (std::uint8_t b : bytes)
        f.data[i++] = b;
    return f;
}

CandumpRecord parsed(std::string_view line)
{
    CandumpRecord r;
    std::string error;
    EXPECT_TRUE(parse_candump_line(line, r, error)) << line << ": " << error;
    return r;
}

std::string parse_error(std::string_view line)
{
    CandumpRecord r;
    std::string error;
    EXPECT_FALSE(parse_candump_line(line, r, error)) << line;
    return error;
}

}  // namespace

TEST(Candump, FormatsExactly)
{
    EXPECT_EQ(format_candump_line(1700000000123456, "can0", frame(0x3A0, {1, 2, 3, 4, 5, 6, 7, 8})),
              "(1700000000.123456) can0 3A0#0102030405060708");
    EXPECT_EQ(format_candump_line(1000001, "vcan0", frame(0x1ABCDEF0, {0xAA}, true)),
              "(0000000001.000001) vcan0 1ABCDEF0#AA");
    EXPECT_EQ(format_candump_line(0, "can1", frame(0x7FF, {})), "(0000000000.000000) can1 7FF#");
    EXPECT_EQ(format_candump_line(5, "can0", frame(0x001, {0x0F, 0xF0})), "(0000000000.000005) can0 001#0FF0");
    EXPECT_EQ(format_candump_line(99999999999000000, "c", frame(0x000, {0})), "(99999999999.000000) c 000#00");
    EXPECT_EQ(format_candump_line(1, "can0", frame(0x0, {}, true)), "(0000000000.000001) can0 00000000#");
}

TEST(Candump, FormatRejectsWhatCandumpCannotPrint)
{
    EXPECT_EQ(format_candump_line(0, "", frame(1, {})), "");
    EXPECT_EQ(format_candump_line(0, "can 0", frame(1, {})), "");
    EXPECT_EQ(format_candump_line(0, "a234567890123456", frame(1, {})), "");  // 16 chars
    EXPECT_NE(format_candump_line(0, "a23456789012345", frame(1, {})), "");   // 15 chars
    EXPECT_EQ(format_candump_line(0, "can0", frame(0x800, {})), "");
    EXPECT_EQ(format_candump_line(0, "can0", frame(0x20000000, {}, true)), "");
    CanFrame f = frame(1, {});
    f.dlc = 9;
    EXPECT_EQ(format_candump_line(0, "can0", f), "");
}

TEST(Candump, FixedBufferNeverOverflows)
{
    const CanFrame f = frame(0x1FFFFFFF, {1, 2, 3, 4, 5, 6, 7, 8}, true);
    const std::string iface(kInterfaceNameMax, 'x');
    std::array<char, kCandumpLineMax + 4> buf{};
    buf.fill('!');
    // The longest line there is fills kCandumpLineMax exactly.
    const std::size_t n = format_candump_line(std::span<char>(buf.data(), kCandumpLineMax),
                                              std::numeric_limits<std::uint64_t>::max(), iface, f);
    EXPECT_EQ(n, kCandumpLineMax);
    EXPECT_EQ(buf[kCandumpLineMax], '!');
    // One byte short: 0, and nothing written past the end.
    buf.fill('!');
    EXPECT_EQ(format_candump_line(std::span<char>(buf.data(), kCandumpLineMax - 1),
                                  std::numeric_limits<std::uint64_t>::max(), iface, f),
              0u);
    EXPECT_EQ(buf[kCandumpLineMax - 1], '!');
}

TEST(Candump, ParsesWhatItWrites)
{
    std::mt19937 rng(5);
    for (int i = 0; i < 2000; ++i) {
        CanFrame f;
        f.extended = rng() % 2 == 0;
        f.id = static_cast<std::uint32_t>(rng()) & (f.extended ? kMaxExtendedId : kMaxStandardId);
        f.dlc = static_cast<std::uint8_t>(rng() % 9);
        for (std::size_t b = 0; b < f.dlc; ++b)
            f.data[b] = static_cast<std::uint8_t>(rng());
        const std::uint64_t t = (std::uint64_t{rng()} << 20) ^ rng();
        const std::string line = format_candump_line(t, "can" + std::to_string(i % 3), f);
        const CandumpRecord r = parsed(line);
        ASSERT_EQ(r.frame, f) << line;
        ASSERT_EQ(r.time_us, t) << line;
        ASSERT_EQ(r.interface, "can" + std::to_string(i % 3));
    }
}

TEST(Candump, ParserAcceptsCandumpVariants)
{
    CandumpRecord r = parsed("(1700000000.123456) can0 3a0#0a0B\n");
    EXPECT_EQ(r.time_us, 1700000000123456u);
    EXPECT_EQ(r.frame, frame(0x3A0, {0x0A, 0x0B}));
    r = parsed("(1.000002)   vcan10 123#\r\n");  // padded device name, CRLF
    EXPECT_EQ(r.time_us, 1000002u);
    EXPECT_EQ(r.interface, "vcan10");
    EXPECT_EQ(r.frame.dlc, 0);
    r = parsed("(0000000001.000000) can0 12345678#1122 R");  // candump -x direction flag
    EXPECT_TRUE(r.frame.extended);
    EXPECT_EQ(r.frame.id, 0x12345678u);
    parsed("(0000000001.000000) can0 123#11 T");
}

TEST(Candump, ParserRejectsWithAReason)
{
    EXPECT_EQ(parse_error(""), "expected '(' and a timestamp");
    EXPECT_EQ(parse_error("1700000000.123456 can0 123#"), "expected '(' and a timestamp");
    EXPECT_EQ(parse_error("(1700000000.12345) can0 123#"),
              "timestamp must be seconds.microseconds with 6 digits of microseconds");
    EXPECT_EQ(parse_error("(17x0000000.123456) can0 123#"), "timestamp: not a number");
    EXPECT_EQ(parse_error("(99999999999999999999.000000) can0 123#"), "timestamp: too large");
    EXPECT_EQ(parse_error("(18446744073709.551616) can0 123#"), "timestamp: too large");  // 2^64 us
    EXPECT_EQ(parsed("(18446744073709.551615) can0 123#").time_us, std::numeric_limits<std::uint64_t>::max());
    EXPECT_EQ(parse_error("(1.000000)can0 123#"), "expected a space after the timestamp");
    EXPECT_EQ(parse_error("(1.000000) can0 123"), "expected ID#DATA");
    EXPECT_EQ(parse_error("(1.000000) can0 1234#"), "identifier must have 3 (11-bit) or 8 (29-bit) hex digits");
    EXPECT_EQ(parse_error("(1.000000) can0 12G#"), "identifier: not hex");
    EXPECT_EQ(parse_error("(1.000000) can0 800#"), "11-bit identifier out of range");
    EXPECT_EQ(parse_error("(1.000000) can0 20000080#0000000000000000"), "29-bit identifier out of range (error frame?)");
    EXPECT_EQ(parse_error("(1.000000) can0 123#112"), "data must be 0 to 8 bytes of 2 hex digits each");
    EXPECT_EQ(parse_error("(1.000000) can0 123#112233445566778899"), "data must be 0 to 8 bytes of 2 hex digits each");
    EXPECT_EQ(parse_error("(1.000000) can0 123#11zz"), "data: not hex");
    EXPECT_EQ(parse_error("(1.000000) can0 123##1112233"), "CAN FD frames are not supported");
    EXPECT_EQ(parse_error("(1.000000) can0 123#R"), "remote frames are not supported");
    EXPECT_EQ(parse_error("(1.000000) can0 123#11 X"), "unexpected text after the frame");
    EXPECT_EQ(parse_error("(1.000000) a234567890123456 123#"), "bad interface name");
}

// can-utils' own log2asc (Debian package can-utils) must read our log.
TEST(Candump, Log2ascReadsTheLog)
{
    if (access("/usr/bin/log2asc", X_OK) != 0)
        GTEST_SKIP() << "can-utils (log2asc) is not installed";
    const auto dir = std::filesystem::temp_directory_path() / ("stemd-candump-test-" + std::to_string(getpid()));
    std::filesystem::create_directories(dir);
    CanFrame target;
    ASSERT_TRUE(encode(TargetCommand{0xABC, 5, 9, 0x12345, -100, PlantClass::Weed}, 3, CanIds{}, target));
    {
        std::ofstream log(dir / "stemd.log");
        log << format_candump_line(1700000000000000, "can0", target) << '\n'
            << format_candump_line(1700000000250000, "can0", frame(0x1ABCDEF0, {0xAA, 0x01}, true)) << '\n'
            << format_candump_line(1700000000500000, "can0", frame(0x7FF, {})) << '\n';
    }
    const std::string cmd = "/usr/bin/log2asc -I " + (dir / "stemd.log").string() + " -O " +
                            (dir / "stemd.asc").string() + " can0";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(dir / "stemd.asc");
    std::stringstream asc;
    asc << in.rdbuf();
    std::filesystem::remove_all(dir);
    const std::string text = asc.str();
    EXPECT_NE(text.find("0.000000 1  301             Rx   d 8 D3 53 BC 9A 45 23 71 BE"), std::string::npos) << text;
    EXPECT_NE(text.find("0.250000 1  1ABCDEF0x       Rx   d 2 AA 01"), std::string::npos) << text;
    EXPECT_NE(text.find("0.500000 1  7FF             Rx   d 0"), std::string::npos) << text;
}
