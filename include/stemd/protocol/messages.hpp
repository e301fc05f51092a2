// stemd's CAN messages: identifiers, signal layout, encode and decode.
// config/stemd.dbc describes the same layout for other tools (cantools,
// SavvyCAN, canmatrix); it is written from the tables below by stemd-dbc
// (dbc_writer.hpp), and a test decodes the encoder's frames with canmatrix.
//
// Every message is a classic CAN frame with an 11-bit identifier and DLC 8,
// protected as described in e2e.hpp (byte 0 CRC, byte 1 low nibble alive
// counter, Data ID = the CAN identifier). Signals are little-endian (Intel,
// DBC "@1"), factor 1, offset 0, so raw value = physical value. Start bits
// count from bit 0 = LSB of byte 0.
//
// Identifier = base + offset; base is configurable (default 0x300, at most 0x7FB).
//
//   ODOMETRY     base+0  DRIVE -> STEMD, TOOL   highest priority: the time base of every fire
//     0|8    e2e_crc
//     8|4    e2e_counter        0..14
//     12|4   (reserved, 0)
//     16|32  odom_mm            u32  mm     distance driven; wraps modulo 2^32
//     48|16  speed_mm_per_s     s16  mm/s   -32767..32767 (forward > 0)
//   TARGET       base+1  STEMD -> TOOL          one weeding command
//     0|8    e2e_crc
//     8|4    e2e_counter        0..14
//     12|4   tool_id            u4          0..15
//     16|12  target_id          u12         0..4095 (the scheduler numbers targets modulo 4096)
//     28|4   lane               u4          0..15
//     32|18  fire_odom_mm       u18  mm     odometer reading at which to fire, modulo 2^18
//     50|12  lateral_mm         s12  mm     -2047..2047, across the direction of travel
//     62|2   plant_class        u2          0 UNKNOWN, 1 CROP, 2 WEED (3 invalid)
//   TOOL_STATUS  base+2  TOOL -> STEMD
//     0|8    e2e_crc
//     8|4    e2e_counter        0..14
//     12|4   (reserved, 0)
//     16|16  tools_ready_mask   u16         bit n set: tool n is ready
//     32|12  last_target_id     u12         last executed target_id
//     44|1   last_target_valid  u1          0 until the tool has executed a target
//     45|3   (reserved, 0)
//     48|8   error_code         u8          ToolError (tool-defined codes pass through)
//     56|8   targets_executed   u8          executed targets, modulo 256
//   HEARTBEAT    base+3  STEMD -> DRIVE, TOOL
//     0|8    e2e_crc
//     8|4    e2e_counter        0..14
//     12|4   state              u4          DaemonState 0..5
//     16|16  targets_sent       u16         TARGET frames sent, modulo 2^16
//     32|12  deadline_misses    u12         saturating at 4095
//     44|12  targets_dropped    u12         saturating at 4095
//     56|8   rx_rejected        u8          received frames rejected (E2E or decode), saturating at 255
//   TOOL_FIRED   base+4  TOOL -> STEMD          one per executed TARGET: where it took effect
//     0|8    e2e_crc
//     8|4    e2e_counter        0..14
//     12|4   tool_id            u4          as in the TARGET (same bits)
//     16|12  target_id          u12         as in the TARGET (same bits)
//     28|4   lane               u4          as in the TARGET (same bits)
//     32|18  fired_odom_mm      u18  mm     odometer reading when the strike took effect, modulo 2^18
//     50|14  (reserved, 0)
//
// TOOL_FIRED has the TARGET's layout for the fields it echoes, so that a tool
// controller copies them bit for bit. fired_odom_mm is the odometer (the
// ODOMETRY scale, modulo 2^18 like fire_odom_mm) when the actuation took
// effect: the valve opened, the stamp touched the ground. A controller that
// cannot sense that reports the odometer when it switched its output plus its
// own known delay times speed. stemd takes fired_odom_mm - fire_odom_mm
// (fire_distance_mm) as the tool's lag.
//
// Reserved bits are sent as 0 and ignored on receive.
//
// fire_odom_mm wrap: the sender puts the odometer reading (the 32-bit odom_mm
// scale of ODOMETRY) modulo 2^18 = 262144 mm. Since 2^18 divides 2^32 the
// truncation stays consistent across the odometer's own wrap. A receiver
// compares it with its odometer modulo 2^18 using fire_distance_mm(), which is
// correct while the fire position is within ±131 m of the current reading.
//
// Counters in HEARTBEAT: targets_sent wraps (a receiver takes differences);
// the error counters saturate, so that they never fall back to small values.
//
// Encode rejects a value outside its signal's range (an enum out of range, an
// id too large, a lateral offset beyond ±2047 mm): nothing is clamped, and the
// result names the signal, for the caller to count. Decode checks identifier,
// DLC, CRC and ranges. Neither allocates nor throws. The alive-counter
// sequence is checked separately, by an E2eChecker per received stream.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "stemd/base/plant_class.hpp"
#include "stemd/protocol/can_frame.hpp"
#include "stemd/protocol/e2e.hpp"

namespace stemd::protocol {

enum class MessageKind : std::uint8_t { Odometry = 0, Target = 1, ToolStatus = 2, Heartbeat = 3, ToolFired = 4 };
inline constexpr std::size_t kMessageKindCount = 5;
inline constexpr std::array<MessageKind, kMessageKindCount> kAllMessageKinds{
    MessageKind::Odometry, MessageKind::Target, MessageKind::ToolStatus, MessageKind::Heartbeat,
    MessageKind::ToolFired};

inline constexpr std::uint16_t kDefaultBaseId = 0x300;
inline constexpr std::uint8_t kFrameDlc = 8;

// ---- layout description (one source of truth for encode, decode and the DBC) ----

struct ValueName {
    std::int64_t value;
    std::string_view name;  // as in the DBC's VAL_ table
};

struct SignalDef {
    std::string_view name;   // the DBC signal name
    std::uint8_t start_bit;  // LSB position, Intel numbering
    std::uint8_t length;     // bits
    bool is_signed;          // two's complement
    std::int64_t min;        // valid range (raw = physical)
    std::int64_t max;
    std::string_view unit;   // "" for none
    std::string_view comment;  // the DBC's CM_ SG_
    std::span<const ValueName> values = {};  // named values (enums), as the DBC's VAL_
};

struct MessageDef {
    MessageKind kind;
    std::string_view name;         // the DBC message name
    std::uint16_t id_offset;       // identifier = base + id_offset
    std::string_view transmitter;  // DBC node
    std::span<const std::string_view> receivers;
    std::span<const SignalDef> signals;  // including e2e_crc and e2e_counter
    std::string_view comment;  // the DBC's CM_ BO_ (the reserved bits are added from the layout)
};

// A node of the network (the DBC's BU_), which transmitters and receivers name.
struct NodeDef {
    std::string_view name;
    std::string_view comment;
};

inline constexpr std::string_view kProtocolVersion = "stemd-can-1";  // the DBC's VERSION

const MessageDef& message_def(MessageKind kind);
std::string_view to_string(MessageKind kind);
// TOOL_STATUS error_code as the DBC names it ("NONE", "NOT_READY", ...); ""
// for a value it does not name.
std::string_view tool_error_name(std::uint8_t code);
std::span<const NodeDef> node_defs();
// The whole protocol in a paragraph (the DBC's network comment).
std::string_view protocol_comment();

// The identifiers for one base ID.
class CanIds {
public:
    static constexpr std::uint32_t kMaxBaseId = kMaxStandardId - (kMessageKindCount - 1);

    CanIds() = default;  // kDefaultBaseId
    // nullopt if base > kMaxBaseId (the last identifier must stay 11-bit).
    static std::optional<CanIds> make(std::uint32_t base_id);

    std::uint16_t base() const { return base_; }
    std::uint16_t id(MessageKind kind) const { return static_cast<std::uint16_t>(base_ + static_cast<std::uint16_t>(kind)); }
    // Which message a received frame is, if it is one of stemd's (11-bit, in range).
    std::optional<MessageKind> kind_of(const CanFrame& frame) const;

private:
    explicit CanIds(std::uint16_t base) : base_(base) {}
    std::uint16_t base_ = kDefaultBaseId;
};

// ---- messages ----

// The plant_class signal's raw values are PlantClass's own.
using stemd::PlantClass;

enum class DaemonState : std::uint8_t {
    Starting = 0,  // initialising, not yet sending targets
    Idle = 1,      // ready, not actuating (disabled, or no odometry)
    Active = 2,    // sending targets
    Degraded = 3,  // sending targets, but something is wrong (deadline misses, lost frames)
    Fault = 4,     // stopped sending targets
    // No frames: the camera is lost (its source is reopening it) or has
    // delivered nothing for source.lost_after_ms. No targets from it.
    CameraLost = 5,
};

// Codes of TOOL_STATUS.error_code. The tool defines them; values not listed
// here are passed through as they are.
namespace tool_error {
inline constexpr std::uint8_t kNone = 0;
inline constexpr std::uint8_t kNotReady = 1;
inline constexpr std::uint8_t kTargetLate = 2;     // fire position already passed on arrival
inline constexpr std::uint8_t kQueueFull = 3;
inline constexpr std::uint8_t kActuatorFault = 4;
inline constexpr std::uint8_t kBadCommand = 5;     // a TARGET failed its E2E or range check
inline constexpr std::uint8_t kOther = 255;
}  // namespace tool_error

inline constexpr std::uint8_t kMaxToolId = 15;
inline constexpr std::uint8_t kMaxLane = 15;
inline constexpr std::uint16_t kMaxTargetId = 4095;
inline constexpr std::int16_t kMaxLateralMm = 2047;  // |lateral_mm| <= this
inline constexpr std::int16_t kMaxSpeedMmPerS = 32767;  // |speed_mm_per_s| <= this
inline constexpr unsigned kFireOdomBits = 18;
inline constexpr std::uint32_t kFireOdomModulo = std::uint32_t{1} << kFireOdomBits;  // 262144 mm

// Signed distance in mm from the odometer reading odom_mm forward to the fire
// position fire_odom_mm, both taken modulo 2^18: in [-131072, 131071].
// Positive: the fire position is still ahead.
constexpr std::int32_t fire_distance_mm(std::uint32_t fire_odom_mm, std::uint32_t odom_mm)
{
    const std::uint32_t d = (fire_odom_mm - odom_mm) & (kFireOdomModulo - 1);
    return d >= kFireOdomModulo / 2 ? static_cast<std::int32_t>(d) - static_cast<std::int32_t>(kFireOdomModulo)
                                    : static_cast<std::int32_t>(d);
}

struct Odometry {
    std::uint32_t odom_mm = 0;
    std::int16_t speed_mm_per_s = 0;  // -32767..32767
    friend bool operator==(const Odometry&, const Odometry&) = default;
};

struct TargetCommand {
    std::uint16_t target_id = 0;  // 0..4095
    std::uint8_t tool_id = 0;     // 0..15
    std::uint8_t lane = 0;        // 0..15
    // Encode: any odometer reading (sent modulo 2^18). Decode: 0..262143.
    std::uint32_t fire_odom_mm = 0;
    std::int16_t lateral_mm = 0;  // -2047..2047
    PlantClass plant_class = PlantClass::Unknown;
    friend bool operator==(const TargetCommand&, const TargetCommand&) = default;
};

struct ToolStatus {
    std::uint16_t tools_ready_mask = 0;
    std::uint16_t last_target_id = 0;  // 0..4095, meaningful if last_target_valid
    bool last_target_valid = false;
    std::uint8_t error_code = tool_error::kNone;
    std::uint8_t targets_executed = 0;  // modulo 256
    friend bool operator==(const ToolStatus&, const ToolStatus&) = default;
};

struct ToolFired {
    std::uint16_t target_id = 0;      // 0..4095, the TARGET's
    std::uint8_t tool_id = 0;         // 0..15, the TARGET's
    std::uint8_t lane = 0;            // 0..15, the TARGET's
    // Encode: any odometer reading (sent modulo 2^18). Decode: 0..262143.
    std::uint32_t fired_odom_mm = 0;
    friend bool operator==(const ToolFired&, const ToolFired&) = default;
};

struct Heartbeat {
    DaemonState state = DaemonState::Starting;
    // Encode: running totals; targets_sent is sent modulo 2^16, the others
    // saturate at their field's maximum. Decode: the field values.
    std::uint64_t targets_sent = 0;
    std::uint64_t deadline_misses = 0;
    std::uint64_t targets_dropped = 0;
    std::uint64_t rx_rejected = 0;
    friend bool operator==(const Heartbeat&, const Heartbeat&) = default;
};

// ---- encode / decode ----

enum class CodecError : std::uint8_t {
    None,
    OutOfRange,   // a value outside its signal's range (see CodecResult::signal)
    BadCounter,   // encode: alive counter > 14
    WrongId,      // decode: not this message's identifier (or an extended frame)
    WrongLength,  // decode: DLC != 8
    WrongCrc,     // decode: E2E CRC mismatch
};
std::string_view to_string(CodecError e);

struct CodecResult {
    CodecError error = CodecError::None;
    std::string_view signal;  // OutOfRange: the DBC name of the offending signal
    explicit operator bool() const { return error == CodecError::None; }
};

// On success `out` is the complete frame; on error `out` is left as it was.
CodecResult encode(const Odometry& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out);
CodecResult encode(const TargetCommand& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out);
CodecResult encode(const ToolStatus& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out);
CodecResult encode(const Heartbeat& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out);
CodecResult encode(const ToolFired& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out);

// Checks identifier, DLC, CRC and every signal's range (not the counter
// sequence: see E2eChecker). On error `out` is left as it was.
CodecResult decode(const CanFrame& frame, const CanIds& ids, Odometry& out);
CodecResult decode(const CanFrame& frame, const CanIds& ids, TargetCommand& out);
CodecResult decode(const CanFrame& frame, const CanIds& ids, ToolStatus& out);
CodecResult decode(const CanFrame& frame, const CanIds& ids, Heartbeat& out);
CodecResult decode(const CanFrame& frame, const CanIds& ids, ToolFired& out);

// A received frame taken as `Message` only if it has 8 bytes, `checker`
// (the receiver's for this message's stream, which counts every outcome)
// accepts its counter and CRC, and it decodes. What every receiver of
// stemd's messages does with each frame.
template <typename Message>
bool decode_checked(const CanFrame& frame, E2eChecker& checker, const CanIds& ids, Message& out)
{
    const std::span<const std::uint8_t, 8> data(frame.data.data(), 8);
    return frame.dlc == 8 && e2e_accepted(checker.check(data)) && static_cast<bool>(decode(frame, ids, out));
}

}  // namespace stemd::protocol
