// Frames from the C++ encoder for the canmatrix check (canmatrix_check.py),
// one per line: a candump -L line, the message name, then every signal but
// e2e_crc as name=value, the value the field must read on the wire:
//
//   (0000000000.000007) can0 301#9B07... TARGET e2e_counter=7 tool_id=3 ... plant_class=2:WEED
//
// ":NAME" is the value's name in the DBC's value table, where the protocol
// names it. The wire values follow the protocol's rules (fire_odom_mm modulo
// 2^18, targets_sent modulo 2^16, the error counters saturating), written here
// by hand, not taken from the library's layout table. Limits, negatives and
// wrap-arounds first, then seeded random values; every message's alive
// counter runs 0..14 and wraps.
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>

#include "stemd/protocol/candump_format.hpp"
#include "stemd/protocol/e2e.hpp"
#include "stemd/protocol/messages.hpp"

using namespace stemd::protocol;

namespace {

std::uint64_t g_time_us = 0;
std::array<E2eCounter, kMessageKindCount> g_counters;
int g_failures = 0;

std::string field(const char* name, std::int64_t value, const char* label = nullptr)
{
    return std::string(" ") + name + "=" + std::to_string(value) + (label ? std::string(":") + label : "");
}

template <typename Msg>
void emit(const Msg& msg, MessageKind kind, const char* name, const std::string& fields)
{
    CanFrame frame;
    const std::uint8_t counter = g_counters[static_cast<std::size_t>(kind)].next();
    const CodecResult r = encode(msg, counter, CanIds{}, frame);
    if (!r) {
        std::fprintf(stderr, "encode %s: %s %.*s\n", name, std::string(to_string(r.error)).c_str(),
                     static_cast<int>(r.signal.size()), r.signal.data());
        ++g_failures;
        return;
    }
    std::printf("%s %s%s%s\n", format_candump_line(g_time_us++, "can0", frame).c_str(), name,
                field("e2e_counter", counter).c_str(), fields.c_str());
}

const char* plant_class_name(PlantClass c)
{
    switch (c) {
    case PlantClass::Unknown: return "UNKNOWN";
    case PlantClass::Crop: return "CROP";
    case PlantClass::Weed: return "WEED";
    }
    return nullptr;
}

const char* state_name(DaemonState s)
{
    switch (s) {
    case DaemonState::Starting: return "STARTING";
    case DaemonState::Idle: return "IDLE";
    case DaemonState::Active: return "ACTIVE";
    case DaemonState::Degraded: return "DEGRADED";
    case DaemonState::Fault: return "FAULT";
    case DaemonState::CameraLost: return "CAMERA_LOST";
    }
    return nullptr;
}

const char* error_name(std::uint8_t code)
{
    switch (code) {
    case 0: return "NONE";
    case 1: return "NOT_READY";
    case 2: return "TARGET_LATE";
    case 3: return "QUEUE_FULL";
    case 4: return "ACTUATOR_FAULT";
    case 5: return "BAD_COMMAND";
    case 255: return "OTHER";
    default: return nullptr;  // passed through, unnamed
    }
}

void target(TargetCommand t)
{
    emit(t, MessageKind::Target, "TARGET",
         field("tool_id", t.tool_id) + field("target_id", t.target_id) + field("lane", t.lane) +
             field("fire_odom_mm", t.fire_odom_mm % 262144) + field("lateral_mm", t.lateral_mm) +
             field("plant_class", static_cast<int>(t.plant_class), plant_class_name(t.plant_class)));
}

void odometry(Odometry o)
{
    emit(o, MessageKind::Odometry, "ODOMETRY", field("odom_mm", o.odom_mm) + field("speed_mm_per_s", o.speed_mm_per_s));
}

void tool_status(ToolStatus s)
{
    emit(s, MessageKind::ToolStatus, "TOOL_STATUS",
         field("tools_ready_mask", s.tools_ready_mask) + field("last_target_id", s.last_target_id) +
             field("last_target_valid", s.last_target_valid ? 1 : 0) +
             field("error_code", s.error_code, error_name(s.error_code)) + field("targets_executed", s.targets_executed));
}

std::int64_t saturated(std::uint64_t value, std::uint64_t max) { return static_cast<std::int64_t>(std::min(value, max)); }

void heartbeat(Heartbeat h)
{
    emit(h, MessageKind::Heartbeat, "HEARTBEAT",
         field("state", static_cast<int>(h.state), state_name(h.state)) +
             field("targets_sent", static_cast<std::int64_t>(h.targets_sent % 65536)) +
             field("deadline_misses", saturated(h.deadline_misses, 4095)) +
             field("targets_dropped", saturated(h.targets_dropped, 4095)) + field("rx_rejected", saturated(h.rx_rejected, 255)));
}

void tool_fired(ToolFired f)
{
    emit(f, MessageKind::ToolFired, "TOOL_FIRED",
         field("tool_id", f.tool_id) + field("target_id", f.target_id) + field("lane", f.lane) +
             field("fired_odom_mm", f.fired_odom_mm % 262144));
}

}  // namespace

int main()
{
    // Limits, negatives, every enum value, the modulo and saturating fields.
    target({0, 0, 0, 0, -2047, PlantClass::Unknown});
    target({4095, 15, 15, 262143, 2047, PlantClass::Weed});
    target({0xA5A, 0xA, 0x5, 0x2A5A5, -1, PlantClass::Crop});
    target({1, 1, 1, 262144 + 17, 1, PlantClass::Weed});       // fire_odom_mm past 2^18 -> 17
    target({2, 2, 2, 0xFFFFFFFFu, -1000, PlantClass::Crop});  // the odometer's own wrap -> 262143
    odometry({0, -32767});
    odometry({0xFFFFFFFFu, 32767});
    odometry({0x80000000u, -1});
    odometry({1, 0});
    tool_status({});
    tool_status({0xFFFF, 4095, true, 255, 255});
    tool_status({0x8001, 0x800, true, 7, 128});  // an error code the protocol does not name
    for (std::uint8_t code = 0; code <= 5; ++code)
        tool_status({static_cast<std::uint16_t>(1u << code), code, code % 2 == 0, code, code});
    for (int s = 0; s <= 5; ++s)
        heartbeat({static_cast<DaemonState>(s), 0, 0, 0, 0});
    heartbeat({DaemonState::Active, 65535, 4095, 4095, 255});
    heartbeat({DaemonState::Active, 65536, 4096, 4096, 256});  // wraps to 0; saturate
    heartbeat({DaemonState::Fault, 70000, 9999, 1u << 20, 300});
    heartbeat({DaemonState::Degraded, ~std::uint64_t{0}, ~std::uint64_t{0}, ~std::uint64_t{0}, ~std::uint64_t{0}});
    tool_fired({0, 0, 0, 0});
    tool_fired({4095, 15, 15, 262143});
    tool_fired({0xA5A, 0xA, 0x5, 0x2A5A5});
    tool_fired({1, 1, 1, 262144 + 17});       // fired_odom_mm past 2^18 -> 17
    tool_fired({2, 2, 2, 0xFFFFFFFFu});       // the odometer's own wrap -> 262143

    // Seeded random values over each field's whole range.
    std::mt19937 rng(99);
    for (int i = 0; i < 100; ++i) {
        target({static_cast<std::uint16_t>(rng() % 4096), static_cast<std::uint8_t>(rng() % 16),
                static_cast<std::uint8_t>(rng() % 16), static_cast<std::uint32_t>(rng()),
                static_cast<std::int16_t>(static_cast<int>(rng() % 4095) - 2047), static_cast<PlantClass>(rng() % 3)});
        odometry({static_cast<std::uint32_t>(rng()), static_cast<std::int16_t>(static_cast<int>(rng() % 65535) - 32767)});
        tool_status({static_cast<std::uint16_t>(rng()), static_cast<std::uint16_t>(rng() % 4096), rng() % 2 == 0,
                     static_cast<std::uint8_t>(rng()), static_cast<std::uint8_t>(rng())});
        heartbeat({static_cast<DaemonState>(rng() % 6), rng(), rng() % 5000, rng() % 5000, rng() % 300});
        tool_fired({static_cast<std::uint16_t>(rng() % 4096), static_cast<std::uint8_t>(rng() % 16),
                    static_cast<std::uint8_t>(rng() % 16), static_cast<std::uint32_t>(rng())});
    }
    return g_failures == 0 && std::fflush(stdout) == 0 ? 0 : 1;
}
