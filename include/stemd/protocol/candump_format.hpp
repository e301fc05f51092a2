// The candump log format (`candump -L`), which canplayer replays and log2asc /
// log2long convert:
//
//   (1700000000.123456) can0 3A0#0102030405060708
//
// - the timestamp in seconds, zero-padded to 10 digits, '.', exactly 6 digits
//   of microseconds (as candump prints "(%010lu.%06lu)");
// - the interface name;
// - the identifier as 3 upper-case hex digits (11-bit) or 8 (29-bit), '#',
//   then 2 upper-case hex digits per data byte (none for DLC 0).
// Classic CAN data frames only: no CAN FD ("##"), no remote frames ("#R"),
// no error frames.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "stemd/protocol/can_frame.hpp"

namespace stemd::protocol {

// Longest line format_candump_line() writes, without a terminator: "(" 14
// digits (the seconds of a 64-bit microsecond count) "." 6 ") " 15-character
// interface " " 8 "#" 16.
inline constexpr std::size_t kCandumpLineMax = 1 + 14 + 1 + 6 + 2 + 15 + 1 + 8 + 1 + 16;
inline constexpr std::size_t kInterfaceNameMax = 15;  // IFNAMSIZ - 1

// True for a name candump could print: 1..15 characters, none of them
// whitespace, '(' , ')' or '#'.
bool valid_interface_name(std::string_view name);

// Writes one line, without '\n', into `out`; returns its length, or 0 (writing
// nothing useful) if `out` is too short, the interface name is invalid, the
// DLC is over 8 or the identifier too large. Allocation-free.
std::size_t format_candump_line(std::span<char> out, std::uint64_t time_us, std::string_view interface,
                                const CanFrame& frame);
// The same as a string ("" on error).
std::string format_candump_line(std::uint64_t time_us, std::string_view interface, const CanFrame& frame);

struct CandumpRecord {
    std::uint64_t time_us = 0;  // seconds * 1000000 + microseconds
    std::string interface;
    CanFrame frame;
};

// Parses one line (a trailing '\n' or "\r\n" is allowed, and so is candump -x's
// trailing direction flag " T" or " R", which is ignored). Hex digits may be
// either case. On failure returns false, leaves `out` unspecified and sets
// `error` to a one-line reason.
bool parse_candump_line(std::string_view line, CandumpRecord& out, std::string& error);

}  // namespace stemd::protocol
