#include "stemd/protocol/messages.hpp"

#include <algorithm>
#include <type_traits>

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
constexpr SignalDef kReadyMask{"tools_ready_mask", 16, 16, false, 0, 0xFFFF, "", "Bit n set: tool n is ready to fire; stemd sends no TARGET to a tool whose bit is clear."};
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
                             "TARGETs not sent: no tool covers the plant or none covering it is ready, enable off, or the send failed; "
                             "saturates at 4095."};
constexpr SignalDef kRxRejected{"rx_rejected", 56, 8, false, 0, 255, "",
                                "Received frames rejected (E2E, decode, or TOOL_FIRED for a tool not configured); saturates at 255."};
constexpr std::array kHeartbeatSignals{kCrc, kCounter, kState, kSent, kDeadlineMisses, kDropped, kRxRejected};

// TOOL_FIRED repeats the TARGET's bits for the fields it echoes.
constexpr SignalDef echo(SignalDef s, std::string_view name, std::string_view comment)
{
    s.name = name;
    s.comment = comment;
    return s;
}
constexpr SignalDef kFiredToolId = echo(kToolId, "tool_id", "TARGET.tool_id of the command executed.");
constexpr SignalDef kFiredTargetId = echo(kTargetId, "target_id", "TARGET.target_id of the command executed.");
constexpr SignalDef kFiredLane = echo(kLane, "lane", "TARGET.lane of the command executed.");
constexpr SignalDef kFiredOdom = echo(kFireOdom, "fired_odom_mm",
                                      "ODOMETRY.odom_mm reading when the strike took effect (valve open, stamp down), "
                                      "modulo 2^18 mm. Minus TARGET.fire_odom_mm: the tool's lag in mm.");
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

// ---- one field table per message: signal, member, and how a value goes on the wire ----

enum class Wire : std::uint8_t {
    exact,     // the member's value, range-checked
    modulo,    // the member's low bits (a running count or an odometer reading)
    saturate,  // the member's value, capped at the signal's maximum
};

template <typename>
struct MemberOf;
template <typename C, typename T>
struct MemberOf<T C::*> {
    using Class = C;
    using Type = T;
};

template <auto Member>
using ClassOf = typename MemberOf<decltype(Member)>::Class;

template <typename Msg>
struct FieldCodec {
    const SignalDef* signal;
    std::int64_t (*to_wire)(const Msg&, const SignalDef&);
    void (*from_wire)(Msg&, std::int64_t);
};

template <auto Member, Wire W>
std::int64_t member_to_wire(const ClassOf<Member>& msg, const SignalDef& s)
{
    const auto v = msg.*Member;
    if constexpr (W == Wire::modulo)
        return static_cast<std::int64_t>(static_cast<std::uint64_t>(v) & ((std::uint64_t{1} << s.length) - 1));
    else if constexpr (W == Wire::saturate)
        return static_cast<std::int64_t>(std::min<std::uint64_t>(v, static_cast<std::uint64_t>(s.max)));
    else
        return static_cast<std::int64_t>(v);
}

template <auto Member>
void member_from_wire(ClassOf<Member>& msg, std::int64_t v)
{
    using T = typename MemberOf<decltype(Member)>::Type;
    if constexpr (std::is_same_v<T, bool>)
        msg.*Member = v != 0;
    else
        msg.*Member = static_cast<T>(v);
}

template <auto Member, Wire W = Wire::exact>
constexpr FieldCodec<ClassOf<Member>> field(const SignalDef& s)
{
    return {&s, &member_to_wire<Member, W>, &member_from_wire<Member>};
}

// A message's fields after the E2E pair, in the order encode and decode
// visit them (the first out-of-range one is the one reported).
template <typename Msg, std::size_t N>
struct FieldTable {
    MessageKind kind;
    std::array<FieldCodec<Msg>, N> fields;
};

template <typename Msg, typename... More>
constexpr FieldTable<Msg, 1 + sizeof...(More)> fields_of(MessageKind kind, FieldCodec<Msg> first, More... more)
{
    return {kind, {first, more...}};
}

constexpr auto kOdometryFields = fields_of(MessageKind::Odometry,
    field<&Odometry::odom_mm>(kOdomMm),
    field<&Odometry::speed_mm_per_s>(kSpeed));
constexpr auto kTargetFields = fields_of(MessageKind::Target,
    field<&TargetCommand::tool_id>(kToolId),
    field<&TargetCommand::target_id>(kTargetId),
    field<&TargetCommand::lane>(kLane),
    field<&TargetCommand::fire_odom_mm, Wire::modulo>(kFireOdom),
    field<&TargetCommand::lateral_mm>(kLateral),
    field<&TargetCommand::plant_class>(kPlantClass));
constexpr auto kToolStatusFields = fields_of(MessageKind::ToolStatus,
    field<&ToolStatus::tools_ready_mask>(kReadyMask),
    field<&ToolStatus::last_target_id>(kLastTargetId),
    field<&ToolStatus::last_target_valid>(kLastTargetValid),
    field<&ToolStatus::error_code>(kErrorCode),
    field<&ToolStatus::targets_executed>(kExecuted));
constexpr auto kHeartbeatFields = fields_of(MessageKind::Heartbeat,
    field<&Heartbeat::state>(kState),
    field<&Heartbeat::targets_sent, Wire::modulo>(kSent),
    field<&Heartbeat::deadline_misses, Wire::saturate>(kDeadlineMisses),
    field<&Heartbeat::targets_dropped, Wire::saturate>(kDropped),
    field<&Heartbeat::rx_rejected, Wire::saturate>(kRxRejected));
constexpr auto kToolFiredFields = fields_of(MessageKind::ToolFired,
    field<&ToolFired::tool_id>(kFiredToolId),
    field<&ToolFired::target_id>(kFiredTargetId),
    field<&ToolFired::lane>(kFiredLane),
    field<&ToolFired::fired_odom_mm, Wire::modulo>(kFiredOdom));

// Every signal but the E2E pair is some member's, in the layout's order.
template <typename Msg, std::size_t N>
constexpr bool fields_match(const FieldTable<Msg, N>& table)
{
    const MessageDef& m = kMessages[static_cast<std::size_t>(table.kind)];
    if (m.signals.size() != N + 2)
        return false;
    for (std::size_t i = 0; i < N; ++i)
        if (m.signals[i + 2].name != table.fields[i].signal->name)
            return false;
    return true;
}
static_assert(fields_match(kOdometryFields) && fields_match(kTargetFields) && fields_match(kToolStatusFields)
                  && fields_match(kHeartbeatFields) && fields_match(kToolFiredFields),
              "field tables cover their messages");

template <typename Msg, std::size_t N>
CodecResult encode_fields(const FieldTable<Msg, N>& table, const Msg& msg, std::uint8_t counter, const CanIds& ids,
                          CanFrame& out)
{
    Packer p;
    for (const FieldCodec<Msg>& f : table.fields)
        p.put(*f.signal, f.to_wire(msg, *f.signal));
    return p.finish(ids, table.kind, counter, out);
}

template <typename Msg, std::size_t N>
CodecResult decode_fields(const FieldTable<Msg, N>& table, const CanFrame& frame, const CanIds& ids, Msg& out)
{
    if (CodecResult r = check_frame(frame, ids, table.kind); !r)
        return r;
    Unpacker u(frame.data);
    Msg m;
    for (const FieldCodec<Msg>& f : table.fields)
        f.from_wire(m, u.get(*f.signal));
    if (CodecResult r = u.result(); !r)
        return r;
    out = m;
    return {};
}

}  // namespace

const MessageDef& message_def(MessageKind kind) { return kMessages[static_cast<std::size_t>(kind)]; }

std::span<const NodeDef> node_defs() { return kNodes; }

std::string_view protocol_comment() { return kProtocolComment; }

std::string_view to_string(MessageKind kind) { return message_def(kind).name; }

std::string_view tool_error_name(std::uint8_t code)
{
    for (const ValueName& v : kToolErrorNames)
        if (v.value == code)
            return v.name;
    return "";
}

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

// ---- the messages' entry points: their field tables ----

CodecResult encode(const Odometry& m, std::uint8_t c, const CanIds& ids, CanFrame& out) { return encode_fields(kOdometryFields, m, c, ids, out); }
CodecResult encode(const TargetCommand& m, std::uint8_t c, const CanIds& ids, CanFrame& out) { return encode_fields(kTargetFields, m, c, ids, out); }
CodecResult encode(const ToolStatus& m, std::uint8_t c, const CanIds& ids, CanFrame& out) { return encode_fields(kToolStatusFields, m, c, ids, out); }
CodecResult encode(const Heartbeat& m, std::uint8_t c, const CanIds& ids, CanFrame& out) { return encode_fields(kHeartbeatFields, m, c, ids, out); }
CodecResult encode(const ToolFired& m, std::uint8_t c, const CanIds& ids, CanFrame& out) { return encode_fields(kToolFiredFields, m, c, ids, out); }

CodecResult decode(const CanFrame& frame, const CanIds& ids, Odometry& out) { return decode_fields(kOdometryFields, frame, ids, out); }
CodecResult decode(const CanFrame& frame, const CanIds& ids, TargetCommand& out) { return decode_fields(kTargetFields, frame, ids, out); }
CodecResult decode(const CanFrame& frame, const CanIds& ids, ToolStatus& out) { return decode_fields(kToolStatusFields, frame, ids, out); }
CodecResult decode(const CanFrame& frame, const CanIds& ids, Heartbeat& out) { return decode_fields(kHeartbeatFields, frame, ids, out); }
CodecResult decode(const CanFrame& frame, const CanIds& ids, ToolFired& out) { return decode_fields(kToolFiredFields, frame, ids, out); }

}  // namespace stemd::protocol
