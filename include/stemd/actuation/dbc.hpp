// A small reader for Vector DBC files: enough to check config/stemd.dbc
// against the encoder, and to decode logged frames by name in tools.
//
// Read: VERSION, NS_ (skipped), BS_, BU_, BO_ with its SG_ lines (both byte
// orders, signed and unsigned, factor/offset/min/max, unit, receivers), CM_
// for the network, nodes, messages and signals, and VAL_. Attribute
// statements (BA_DEF_, BA_DEF_DEF_, BA_, ...), VAL_TABLE_, BO_TX_BU_ and
// SIG_GROUP_ are skipped. Not supported (an error): multiplexed signals and
// SIG_VALTYPE_ (float signals). Not for the real-time path: it allocates.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace stemd::actuation::dbc {

struct Signal {
    std::string name;
    unsigned start_bit = 0;  // Intel: the LSB; Motorola: the MSB (DBC "sawtooth" numbering)
    unsigned length = 0;
    bool little_endian = true;  // "@1" (Intel); "@0" is Motorola
    bool is_signed = false;     // "-"
    double factor = 1;
    double offset = 0;
    double min = 0;
    double max = 0;
    std::string unit;
    std::vector<std::string> receivers;  // "Vector__XXX" (none) is left out
    std::string comment;
    std::map<std::int64_t, std::string> values;  // VAL_

    // True if every bit of the signal lies within `dlc` bytes.
    bool fits(unsigned dlc) const;
    // The raw value (sign-extended if signed) from the frame's bytes; the
    // signal must fit data.size() bytes.
    std::int64_t raw(std::span<const std::uint8_t> data) const;
    // raw * factor + offset.
    double physical(std::span<const std::uint8_t> data) const;
};

struct Message {
    std::uint32_t id = 0;  // without the extended flag
    bool extended = false;  // DBC id had bit 31 set
    std::string name;
    unsigned dlc = 0;
    std::string transmitter;
    std::vector<Signal> signals;
    std::string comment;

    const Signal* signal(std::string_view name) const;
};

struct Database {
    std::string version;
    std::vector<std::string> nodes;
    std::vector<Message> messages;
    std::string comment;
    std::map<std::string, std::string, std::less<>> node_comments;

    const Message* message(std::string_view name) const;
    const Message* message_by_id(std::uint32_t id, bool extended = false) const;
};

// On failure: nullopt and `error` = "line N: reason".
std::optional<Database> parse(std::string_view text, std::string& error);
// On failure: nullopt and `error` = "<path>: ..." or "<path>:N: reason".
std::optional<Database> read_file(const std::filesystem::path& path, std::string& error);

}  // namespace stemd::actuation::dbc
