// End-to-end protection of every stemd CAN message, after AUTOSAR E2E profile 11
// (the CAN profile; configuration "DataIDMode = BOTH", CRC at bit 0, counter at bit 8).
//
// Layout of the 8 data bytes (Intel bit numbering, bit 0 = LSB of byte 0):
//
//   byte 0        bits 0..7    e2e_crc      CRC-8 SAE J1850 (see crc8.hpp)
//   byte 1 low    bits 8..11   e2e_counter  alive counter 0..14, +1 per frame sent, 14 -> 0
//   byte 1 high   bits 12..15  payload (message-specific, protected by the CRC)
//   bytes 2..7    bits 16..63  payload
//
// The CRC covers, in this order: the low byte of the 16-bit Data ID, its high
// byte, then data bytes 1..7 (everything but the CRC byte itself). The Data ID
// is not transmitted; it is the message's 11-bit CAN identifier (so a frame
// that reaches the wrong identifier, or a receiver configured with another
// base ID, fails the CRC). Equivalently, with AUTOSAR's API:
//
//   crc = Crc_CalculateCRC8(&id_lo, 1, 0xFF, TRUE);
//   crc = Crc_CalculateCRC8(&id_hi, 1, crc, FALSE);
//   crc = Crc_CalculateCRC8(&data[1], 7, crc, FALSE);
//
// Counter value 15 is never sent; a receiver treats it as a sequence error.
//
// Receiver (E2eChecker), per message stream, following E2E_P11Check:
// - CRC mismatch -> WrongCrc; the frame is dropped and the state is untouched.
// - Otherwise, with delta = (received - last) mod 15:
//     first valid frame (or after reset()) -> Initial (accepted, syncs the counter)
//     delta == 0                           -> Repeated      (rejected)
//     delta == 1                           -> Ok            (accepted)
//     2 <= delta <= max_delta_counter      -> OkSomeLost    (accepted; delta-1 frames lost)
//     delta > max_delta_counter            -> WrongSequence (rejected)
//   and the last counter becomes the received one (as in AUTOSAR), so after a
//   jump the stream resynchronises: the next consecutive frame is Ok again.
// - A received counter of 15 -> WrongSequence; the state is untouched.
// A 4-bit counter cannot see a loss of a multiple of 15 frames: detecting a
// silent sender (timeout) is the job of the receive loop, not of this check.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>

namespace stemd::protocol {

inline constexpr std::uint8_t kE2eMaxCounter = 14;  // counters run 0..14
inline constexpr std::uint8_t kE2eCounterModulo = kE2eMaxCounter + 1;

// The CRC of an 8-byte payload for a Data ID (byte 0 is ignored).
std::uint8_t e2e_crc(std::uint16_t data_id, std::span<const std::uint8_t, 8> data);

// Writes the counter into the low nibble of byte 1 (the high nibble is kept)
// and then the CRC into byte 0. Returns false, writing nothing, if counter > 14.
bool e2e_protect(std::uint16_t data_id, std::uint8_t counter, std::span<std::uint8_t, 8> data);

// The counter and CRC as transmitted.
inline std::uint8_t e2e_counter_of(std::span<const std::uint8_t, 8> data) { return data[1] & 0x0F; }
inline std::uint8_t e2e_crc_of(std::span<const std::uint8_t, 8> data) { return data[0]; }

// True if byte 0 holds the right CRC for this Data ID.
bool e2e_crc_ok(std::uint16_t data_id, std::span<const std::uint8_t, 8> data);

// Sender side: the alive counter, 0, 1, ..., 14, 0, ...
class E2eCounter {
public:
    // The counter for the next frame; advances.
    std::uint8_t next()
    {
        const std::uint8_t value = value_;
        value_ = static_cast<std::uint8_t>(value_ == kE2eMaxCounter ? 0 : value_ + 1);
        return value;
    }
    std::uint8_t peek() const { return value_; }

private:
    std::uint8_t value_ = 0;
};

enum class E2eStatus : std::uint8_t {
    Initial,        // first valid frame since construction or reset(): accepted
    Ok,             // counter +1: accepted
    OkSomeLost,     // counter +2..+max_delta_counter: accepted, frames were lost
    Repeated,       // same counter as the last frame: rejected
    WrongSequence,  // counter jumped too far (or is 15): rejected
    WrongCrc,       // CRC mismatch: rejected
};
inline constexpr std::size_t kE2eStatusCount = 6;

// Accepted statuses: Initial, Ok, OkSomeLost.
constexpr bool e2e_accepted(E2eStatus s)
{
    return s == E2eStatus::Initial || s == E2eStatus::Ok || s == E2eStatus::OkSomeLost;
}
std::string_view to_string(E2eStatus s);

// Receiver side: checks one message stream (one Data ID) and counts every outcome.
// Allocation-free; not thread-safe (one checker per receive thread and stream).
class E2eChecker {
public:
    // max_delta_counter: the largest accepted counter step, clamped into [1, 14].
    // 1 = no loss tolerated.
    explicit E2eChecker(std::uint16_t data_id, std::uint8_t max_delta_counter = 1);

    E2eStatus check(std::span<const std::uint8_t, 8> data);

    // The next valid frame is Initial again (counts are kept).
    void reset() { synced_ = false; }

    std::uint16_t data_id() const { return data_id_; }
    std::uint8_t max_delta_counter() const { return max_delta_; }
    std::uint64_t count(E2eStatus s) const { return counts_[static_cast<std::size_t>(s)]; }
    std::uint64_t accepted() const;
    std::uint64_t rejected() const;
    // Frames known lost from counter steps (delta - 1 summed over OkSomeLost).
    std::uint64_t lost() const { return lost_; }

private:
    std::uint16_t data_id_;
    std::uint8_t max_delta_;
    bool synced_ = false;
    std::uint8_t last_counter_ = 0;
    std::array<std::uint64_t, kE2eStatusCount> counts_{};
    std::uint64_t lost_ = 0;
};

}  // namespace stemd::protocol
