#include "stemd/protocol/messages.hpp"

#include <algorithm>

#include "stemd/protocol/e2e.hpp"

namespace stemd::protocol {

namespace {

// ---- the layout (see the table in messages.hpp) ----
// Units and comments are the DBC's (dbc_writer.hpp writes config/stemd.dbc
// from these tables); comments must not contain '"'.

constexpr SignalDef kCrc{"e2e_crc", 0, 8, false, 0, 255, "",
                         "E2E profile 11 CRC-8 SAE J1850 over Data ID (= CAN id, low byte then high byte) and bytes 1..7."};
constexpr SignalDef kCounter{"e2e_counter", 8, 4, false, 0, kE2eMaxCounter, "",
                             "E2E profile 11 alive counter 0..14, +1 per frame, wraps 14 -> 0."};

constexpr SignalDef kOdomMm{"odom_mm", 16, 32, false, 0, 0xFFFFFFFF, "mm",
                            "Distance driven since power-up; wraps modulo 2^32 mm."};
constexpr SignalDef kSpeed{"speed_mm_per_s", 48, 16, true, -kMaxSpeedMmPerS, kMaxSpeedMmPerS, "mm/s",
                           "Ground speed, forward positive."};
constexpr std::array kOdometrySignals{kCrc, kCounter, kOdomMm, kSpeed};

constexpr std::array kPlantClassNames{ValueName{0, "UNKNOWN"}, ValueName{1, "CROP"}, ValueName{2, "WEED"}};
constexpr SignalDef kToolId{"tool_id", 12, 4, false, 0, kMaxToolId, "", "The tool that is to fire."};
constexpr SignalDef kTargetId{"target_id", 16, 12, false, 0, kMaxTargetId, "",
                              "Target number assigned by stemd, modulo 4096; echoed in TOOL_STATUS.last_target_id and TOOL_FIRED."};
constexpr SignalDef kLane{"lane", 28, 4, false, 0, kMaxLane, "", "Crop row (lane) of the target."};
constexpr SignalDef kFireOdom{"fire_odom_mm", 32, kFireOdomBits, false, 0, kFireOdomModulo - 1, "mm",
                              "ODOMETRY.odom_mm reading at which to fire, modulo 2^18 mm. Compare with odom_mm "
                              "modulo 2^18 as a signed difference in [-131072, 131071] mm."};
constexpr SignalDef kLateral{"lateral_mm", 50, 12, true, -kMaxLateralMm, kMaxLateralMm, "mm",
                             "Lateral position of the target across the direction of travel."};
constexpr SignalDef kPlantClass{"plant_class", 62, 2, false, 0, 2, "", "What the target is.", kPlantClassNames};
constexpr std::array kTargetSignals{kCrc, kCounter, kToolId, kTargetId, kLane, kFireOdom, kLateral, kPlantClass};

constexpr std::array kToolErrorNames{
    ValueName{tool_error::kNone, "NONE"},
    ValueName{tool_error::kNotReady, "NOT_READY"},
    ValueName{tool_error::kTargetLate, "TARGET_LATE"},
    ValueName{tool_error::kQueueFull, "QUEUE_FULL"},
    ValueName{tool_error::kActuatorFault, "ACTUATOR_FAULT"},
    ValueName{tool_error::kBadCommand, "BAD_COMMAND"},
    ValueName{tool_error::kOther, "OTHER"},
};
constexpr SignalDef kReadyMask{"tools_ready_mask", 16, 16, false, 0, 0xFFFF, "", "Bit n set: tool n is ready to fire."};
constexpr SignalDef kLastTargetId{"last_target_id", 32, 12, false, 0, kMaxTargetId, "",
                                  "target_id of the last executed TARGET; valid if last_target_valid."};
constexpr SignalDef kLastTargetValid{"last_target_valid", 44, 1, false, 0, 1, "", "0 until the tool has executed a target."};
constexpr SignalDef kErrorCode{"error_code", 48, 8, false, 0, 255, "",
                               "Tool error; codes other than those listed pass through.", kToolErrorNames};
constexpr SignalDef kExecuted{"targets_executed", 56, 8, false, 0, 255, "", "Targets executed, modulo 256."};
constexpr std::array kToolStatusSignals{kCrc, kCounter, kReadyMask, kLastTargetId, kLastTargetValid, kErrorCode, kExecuted};

constexpr std::array kStateNames{
    ValueName{0, "STARTING"}, ValueName{1, "IDLE"}, ValueName{2, "ACTIVE"},
    ValueName{3, "DEGRADED"}, ValueName{4, "FAULT"}, ValueName{5, "CAMERA_LOST"},
};
constexpr SignalDef kState{"state", 12, 4, false, 0, 5, "", "Daemon state.", kStateNames};
constexpr SignalDef kSent{"targets_sent", 16, 16, false, 0, 0xFFFF, "", "TARGET frames sent, modulo 2^16."};
constexpr SignalDef kDeadlineMisses{"deadline_misses", 32, 12, false, 0, 4095, "",
                                    "Targets that missed their deadline; saturates at 4095."};
constexpr SignalDef kDropped{"targets_dropped", 44, 12, false, 0, 4095, "",
                             "Targets dropped (queue full, encode error); saturates at 4095."};
constexpr SignalDef kRxRejected{"rx_rejected", 56, 8, false, 0, 255, "",
                                "Received frames rejected (E2E or decode); saturates at 255."};
constexpr std::array kHeartbeatSignals{kCrc, kCounter, kState, kSent, kDeadlineMisses, kDropped, kRxRejected};

// TOOL_FIRED repeats the TARGET's bits for the fields it echoes.
constexpr SignalDef kFiredToolId{"tool_id", 12, 4, false, 0, kMaxToolId, "", "TARGET.tool_id of the command executed."};
constexpr SignalDef kFiredTargetId{"target_id", 16, 12, false, 0, kMaxTargetId, "",
                                   "TARGET.target_id of the command executed."};
constexpr SignalDef kFiredLane{"lane", 28, 4, false, 0, kMaxLane, "", "TARGET.lane of the command executed."};
constexpr SignalDef kFiredOdom{"fired_odom_mm", 32, kFireOdomBits, false, 0, kFireOdomModulo - 1, "mm",
                               "ODOMETRY.odom_mm reading when the strike took effect (valve open, stamp down), "
                               "modulo 2^18 mm. Minus TARGET.fire_odom_mm: the tool's lag in mm."};
constexpr std::array kToolFiredSignals{kCrc, kCounter, kFiredToolId, kFiredTargetId, kFiredLane, kFiredOdom};

constexpr std::array kNodes{
    NodeDef{"STEMD", "The stem-detection daemon: sends weeding targets and its heartbeat."},
    NodeDef{"DRIVE", "The drive controller: sends odometry."},
    NodeDef{"TOOL", "The weeding tool controller: executes targets, reports its status."},
};

constexpr std::array<std::string_view, 2> kToStemdAndTool{"STEMD", "TOOL"};
constexpr std::array<std::string_view, 1> kToTool{"TOOL"};
constexpr std::array<std::string_view, 1> kToStemd{"STEMD"};
constexpr std::array<std::string_view, 2> kToDriveAndTool{"DRIVE", "TOOL"};

constexpr std::array<MessageDef, kMessageKindCount> kMessages{
    MessageDef{MessageKind::Odometry, "ODOMETRY", 0, "DRIVE", kToStemdAndTool, kOdometrySignals,
               "Odometry from the drive: the time base of every fire decision, hence the highest priority."},
    MessageDef{MessageKind::Target, "TARGET", 1, "STEMD", kToTool, kTargetSignals,
               "A weeding command from stemd: fire tool tool_id when the odometer reaches fire_odom_mm."},
    MessageDef{MessageKind::ToolStatus, "TOOL_STATUS", 2, "TOOL", kToStemd, kToolStatusSignals,
               "Status of the weeding tool controller."},
    MessageDef{MessageKind::Heartbeat, "HEARTBEAT", 3, "STEMD", kToDriveAndTool, kHeartbeatSignals,
               "Heartbeat of stemd."},
    MessageDef{MessageKind::ToolFired, "TOOL_FIRED", 4, "TOOL", kToStemd, kToolFiredSignals,
               "One per executed TARGET: the odometer reading at which the strike took effect, for stemd's "
               "lag statistics and latency compensation."},
};

constexpr std::string_view kProtocolComment =
    "stemd weeding-robot CAN protocol. Classic CAN, 11-bit identifiers, DLC 8, little-endian (Intel) signals, "
    "factor 1. Identifiers are base + offset: ODOMETRY +0, TARGET +1, TOOL_STATUS +2, HEARTBEAT +3, TOOL_FIRED +4. "
    "This file is written for the default base 0x300; stemd's base is configurable (at most 0x7FB). Every message is protected "
    "like AUTOSAR E2E profile 11 (DataIDMode BOTH): byte 0 is a CRC-8 SAE J1850 (poly 0x1D, init 0xFF, xor-out "
    "0xFF) over the Data ID low byte, the Data ID high byte and data bytes 1..7; the Data ID is the message's CAN "
    "identifier and is not transmitted. The low nibble of byte 1 is an alive counter 0..14, +1 per frame, 14 -> 0 "
    "(15 is never sent). A receiver rejects and counts frames with a bad CRC, a repeated counter or a counter jump "
    "beyond its tolerance. Reserved bits are sent as 0 and ignored on receive.";

constexpr bool is_node(std::string_view name)
{
    for (const NodeDef& n : kNodes)
        if (n.name == name)
            return true;
    return false;
}

// A DBC string cannot hold a double quote.
constexpr bool dbc_string_ok(std::string_view text) { return text.find('"') == std::string_view::npos; }

// The layout is sound: every signal fits, none overlaps, ranges fit their bits,
// every node named is declared, and every text can be a DBC string.
constexpr bool layout_ok()
{
    for (std::size_t k = 0; k < kMessages.size(); ++k) {
        const MessageDef& m = kMessages[k];
        if (static_cast<std::size_t>(m.kind) != k || m.id_offset != k)
            return false;
        std::uint64_t used = 0;
        for (const SignalDef& s : m.signals) {
            if (s.length == 0 || s.length > 32 || s.start_bit + s.length > 64)
                return false;
            const std::uint64_t bits = ((std::uint64_t{1} << s.length) - 1) << s.start_bit;
            if (used & bits)
                return false;
            used |= bits;
            const std::int64_t lo = s.is_signed ? -(std::int64_t{1} << (s.length - 1)) : 0;
            const std::int64_t hi = s.is_signed ? (std::int64_t{1} << (s.length - 1)) - 1
                                                : (std::int64_t{1} << s.length) - 1;
            if (s.min < lo || s.max > hi || s.min > s.max)
                return false;
        }
        if (m.signals.size() < 2 || m.signals[0].name != "e2e_crc" || m.signals[1].name != "e2e_counter")
            return false;
        if (!is_node(m.transmitter) || !dbc_string_ok(m.comment))
            return false;
        for (std::string_view r : m.receivers)
            if (!is_node(r))
                return false;
        for (const SignalDef& s : m.signals)
            if (!dbc_string_ok(s.unit) || !dbc_string_ok(s.comment))
                return false;
    }
    for (const NodeDef& n : kNodes)
        if (!dbc_string_ok(n.comment))
            return false;
    return dbc_string_ok(kProtocolComment);
}
static_assert(layout_ok(), "CAN message layout");

// ---- bit packing: the 8 bytes as one little-endian 64-bit word ----

using Payload = std::array<std::uint8_t, 8>;

class Packer {
public:
    // Range-checks and stores a value; remembers the first offending signal.
    void put(const SignalDef& s, std::int64_t value)
    {
        if (value < s.min || value > s.max) {
            if (bad_.empty())
                bad_ = s.name;
            return;
        }
        const std::uint64_t mask = (std::uint64_t{1} << s.length) - 1;
        word_ |= (static_cast<std::uint64_t>(value) & mask) << s.start_bit;
    }

    CodecResult finish(const CanIds& ids, MessageKind kind, std::uint8_t counter, CanFrame& out) const
    {
        if (!bad_.empty())
            return {CodecError::OutOfRange, bad_};
        if (counter > kE2eMaxCounter)
            return {CodecError::BadCounter, kCounter.name};
        CanFrame f;
        f.id = ids.id(kind);
        f.extended = false;
        f.dlc = kFrameDlc;
        for (std::size_t i = 0; i < 8; ++i)
            f.data[i] = static_cast<std::uint8_t>(word_ >> (8 * i));
        e2e_protect(static_cast<std::uint16_t>(f.id), counter, f.data);
        out = f;
        return {};
    }

private:
    std::uint64_t word_ = 0;
    std::string_view bad_;
};

class Unpacker {
public:
    explicit Unpacker(const Payload& data)
    {
        for (std::size_t i = 0; i < 8; ++i)
            word_ |= static_cast<std::uint64_t>(data[i]) << (8 * i);
    }

    // The value, range-checked; remembers the first offending signal.
    std::int64_t get(const SignalDef& s)
    {
        const std::uint64_t mask = (std::uint64_t{1} << s.length) - 1;
        const std::uint64_t raw = (word_ >> s.start_bit) & mask;
        std::int64_t value = static_cast<std::int64_t>(raw);
        if (s.is_signed && (raw >> (s.length - 1)))
            value -= std::int64_t{1} << s.length;
        if ((value < s.min || value > s.max) && bad_.empty())
            bad_ = s.name;
        return value;
    }

    CodecResult result() const
    {
        if (!bad_.empty())
            return {CodecError::OutOfRange, bad_};
        return {};
    }

private:
    std::uint64_t word_ = 0;
    std::string_view bad_;
};

CodecResult check_frame(const CanFrame& frame, const CanIds& ids, MessageKind kind)
{
    if (frame.extended || frame.id != ids.id(kind))
        return {CodecError::WrongId, {}};
    if (frame.dlc != kFrameDlc)
        return {CodecError::WrongLength, {}};
    if (!e2e_crc_ok(static_cast<std::uint16_t>(frame.id), frame.data))
        return {CodecError::WrongCrc, kCrc.name};
    return {};
}

template <typename T>
constexpr T narrow(std::int64_t v)
{
    return static_cast<T>(v);
}

std::int64_t saturate(std::uint64_t v, const SignalDef& s)
{
    return static_cast<std::int64_t>(std::min<std::uint64_t>(v, static_cast<std::uint64_t>(s.max)));
}

}  // namespace

const MessageDef& message_def(MessageKind kind) { return kMessages[static_cast<std::size_t>(kind)]; }

std::span<const NodeDef> node_defs() { return kNodes; }

std::string_view protocol_comment() { return kProtocolComment; }

std::string_view to_string(MessageKind kind) { return message_def(kind).name; }

std::optional<CanIds> CanIds::make(std::uint32_t base_id)
{
    if (base_id > kMaxBaseId)
        return std::nullopt;
    return CanIds(static_cast<std::uint16_t>(base_id));
}

std::optional<MessageKind> CanIds::kind_of(const CanFrame& frame) const
{
    if (frame.extended || frame.id < base_ || frame.id >= base_ + kMessageKindCount)
        return std::nullopt;
    return static_cast<MessageKind>(frame.id - base_);
}

std::string_view to_string(CodecError e)
{
    switch (e) {
    case CodecError::None: return "ok";
    case CodecError::OutOfRange: return "out of range";
    case CodecError::BadCounter: return "bad alive counter";
    case CodecError::WrongId: return "wrong identifier";
    case CodecError::WrongLength: return "wrong length";
    case CodecError::WrongCrc: return "wrong CRC";
    }
    return "?";
}

// ---- ODOMETRY ----

CodecResult encode(const Odometry& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out)
{
    Packer p;
    p.put(kOdomMm, msg.odom_mm);
    p.put(kSpeed, msg.speed_mm_per_s);
    return p.finish(ids, MessageKind::Odometry, counter, out);
}

CodecResult decode(const CanFrame& frame, const CanIds& ids, Odometry& out)
{
    if (CodecResult r = check_frame(frame, ids, MessageKind::Odometry); !r)
        return r;
    Unpacker u(frame.data);
    Odometry m;
    m.odom_mm = narrow<std::uint32_t>(u.get(kOdomMm));
    m.speed_mm_per_s = narrow<std::int16_t>(u.get(kSpeed));
    if (CodecResult r = u.result(); !r)
        return r;
    out = m;
    return {};
}

// ---- TARGET ----

CodecResult encode(const TargetCommand& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out)
{
    Packer p;
    p.put(kToolId, msg.tool_id);
    p.put(kTargetId, msg.target_id);
    p.put(kLane, msg.lane);
    p.put(kFireOdom, msg.fire_odom_mm & (kFireOdomModulo - 1));  // modulo 2^18 by design
    p.put(kLateral, msg.lateral_mm);
    p.put(kPlantClass, to_value(msg.plant_class));
    return p.finish(ids, MessageKind::Target, counter, out);
}

CodecResult decode(const CanFrame& frame, const CanIds& ids, TargetCommand& out)
{
    if (CodecResult r = check_frame(frame, ids, MessageKind::Target); !r)
        return r;
    Unpacker u(frame.data);
    TargetCommand m;
    m.tool_id = narrow<std::uint8_t>(u.get(kToolId));
    m.target_id = narrow<std::uint16_t>(u.get(kTargetId));
    m.lane = narrow<std::uint8_t>(u.get(kLane));
    m.fire_odom_mm = narrow<std::uint32_t>(u.get(kFireOdom));
    m.lateral_mm = narrow<std::int16_t>(u.get(kLateral));
    m.plant_class = static_cast<PlantClass>(u.get(kPlantClass));
    if (CodecResult r = u.result(); !r)
        return r;
    out = m;
    return {};
}

// ---- TOOL_STATUS ----

CodecResult encode(const ToolStatus& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out)
{
    Packer p;
    p.put(kReadyMask, msg.tools_ready_mask);
    p.put(kLastTargetId, msg.last_target_id);
    p.put(kLastTargetValid, msg.last_target_valid ? 1 : 0);
    p.put(kErrorCode, msg.error_code);
    p.put(kExecuted, msg.targets_executed);
    return p.finish(ids, MessageKind::ToolStatus, counter, out);
}

CodecResult decode(const CanFrame& frame, const CanIds& ids, ToolStatus& out)
{
    if (CodecResult r = check_frame(frame, ids, MessageKind::ToolStatus); !r)
        return r;
    Unpacker u(frame.data);
    ToolStatus m;
    m.tools_ready_mask = narrow<std::uint16_t>(u.get(kReadyMask));
    m.last_target_id = narrow<std::uint16_t>(u.get(kLastTargetId));
    m.last_target_valid = u.get(kLastTargetValid) != 0;
    m.error_code = narrow<std::uint8_t>(u.get(kErrorCode));
    m.targets_executed = narrow<std::uint8_t>(u.get(kExecuted));
    if (CodecResult r = u.result(); !r)
        return r;
    out = m;
    return {};
}

// ---- HEARTBEAT ----

CodecResult encode(const Heartbeat& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out)
{
    Packer p;
    p.put(kState, static_cast<std::int64_t>(msg.state));
    p.put(kSent, static_cast<std::int64_t>(msg.targets_sent & 0xFFFF));  // modulo 2^16 by design
    p.put(kDeadlineMisses, saturate(msg.deadline_misses, kDeadlineMisses));
    p.put(kDropped, saturate(msg.targets_dropped, kDropped));
    p.put(kRxRejected, saturate(msg.rx_rejected, kRxRejected));
    return p.finish(ids, MessageKind::Heartbeat, counter, out);
}

CodecResult decode(const CanFrame& frame, const CanIds& ids, Heartbeat& out)
{
    if (CodecResult r = check_frame(frame, ids, MessageKind::Heartbeat); !r)
        return r;
    Unpacker u(frame.data);
    Heartbeat m;
    m.state = static_cast<DaemonState>(u.get(kState));
    m.targets_sent = static_cast<std::uint64_t>(u.get(kSent));
    m.deadline_misses = static_cast<std::uint64_t>(u.get(kDeadlineMisses));
    m.targets_dropped = static_cast<std::uint64_t>(u.get(kDropped));
    m.rx_rejected = static_cast<std::uint64_t>(u.get(kRxRejected));
    if (CodecResult r = u.result(); !r)
        return r;
    out = m;
    return {};
}

// ---- TOOL_FIRED ----

CodecResult encode(const ToolFired& msg, std::uint8_t counter, const CanIds& ids, CanFrame& out)
{
    Packer p;
    p.put(kFiredToolId, msg.tool_id);
    p.put(kFiredTargetId, msg.target_id);
    p.put(kFiredLane, msg.lane);
    p.put(kFiredOdom, msg.fired_odom_mm & (kFireOdomModulo - 1));  // modulo 2^18 by design
    return p.finish(ids, MessageKind::ToolFired, counter, out);
}

CodecResult decode(const CanFrame& frame, const CanIds& ids, ToolFired& out)
{
    if (CodecResult r = check_frame(frame, ids, MessageKind::ToolFired); !r)
        return r;
    Unpacker u(frame.data);
    ToolFired m;
    m.tool_id = narrow<std::uint8_t>(u.get(kFiredToolId));
    m.target_id = narrow<std::uint16_t>(u.get(kFiredTargetId));
    m.lane = narrow<std::uint8_t>(u.get(kFiredLane));
    m.fired_odom_mm = narrow<std::uint32_t>(u.get(kFiredOdom));
    if (CodecResult r = u.result(); !r)
        return r;
    out = m;
    return {};
}

}  // namespace stemd::protocol
