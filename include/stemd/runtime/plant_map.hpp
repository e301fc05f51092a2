// The plant map (--map FILE, map.file): one JSON object per line for every
// plant the tracker followed, written when its track ends (it left the view,
// went unseen, or the run ended):
//
//   {"id":17,"s_mm":1234.6,"y_mm":-40.2,"class":"weed","leaves":4,"sightings":7,
//    "first_frame":120,"last_frame":126,"treated":true,"reason":"sent",
//    "tool":0,"lane":0,"fire_odom_mm":1834.6}
//
// id: the TARGET target_id (0..4095, wraps), or -1 for a track that was
// never confirmed (a detection seen too few times: a likely false positive).
// s_mm, y_mm: field coordinates (README, "Machine frame and field
// coordinates"), fused over every sighting. class: unknown|crop|weed.
// first_frame/last_frame: the daemon's frame numbers. treated: a TARGET
// went onto the bus. reason: sent, or why not: policy, no_tool, disabled,
// not_ready (no tool covering it was ready: TOOL_STATUS),
// deadline_miss (the scheduler: it could not be on time), bus_deadline (the
// bus could not take it before its deadline), bus_error, no_odometry,
// unconfirmed. tool, lane, fire_odom_mm: when a tool was chosen.
// With gnss.source set, more keys end the line: "lat_deg", "lon_deg"
// (WGS84, 1e-9 degree; null without a position), "georef" (fix,
// extrapolated, degraded, no_fix, stale, no_heading:
// runtime/gnss_input.hpp), and the quality of the fixes the position came
// from: "gnss_mode" (none, 2d, 3d), "gnss_status" (gpsd's: gps, dgps,
// rtk_fixed, rtk_float, ...; none when unknown) and "eph_mm" (horizontal
// error estimate, null when the receiver gives none). degraded: placed,
// but eph_mm is above gnss.max_eph_mm.
//
// Tool timing, appended after those when a TARGET was sent: fire_lead_mm
// (how much earlier than the stem it was commanded, speed × latency_ms), and
// once the tool's TOOL_FIRED came back fired_odom_mm, fire_lag_mm (fired -
// commanded), fire_lag_ms (null when standing) and strike_mm (fired - stem:
// > 0 late). Once a tool has reported a strike, the line of a plant sent to
// it waits for its TOOL_FIRED, until the odometer is 1 m past its point
// (then it is written without them): lines are then not always in the
// order the tracks ended, and a kill loses the waiting ones. Plants that
// left the view before their tool's first report have no such columns.
//
// Formatted by the actuator thread into a fixed buffer, without allocating.
// In the daemon the line is then handed to the writer thread
// (record_writer.hpp), which makes the one write(2) per line
// (base::RecordFile): a slow disk does not hold up the actuator, a kill
// leaves no torn line and loses only the lines of the last millisecond or
// so. Without a writer (tests, tools) write() makes the write(2) itself.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string_view>

#include <spdlog/logger.h>

#include "stemd/actuation/tracker.hpp"
#include "stemd/runtime/gnss_input.hpp"
#include "stemd/runtime/record_output.hpp"

namespace stemd::runtime {

enum class MapReason : std::uint8_t {
    sent, policy, no_tool, disabled, not_ready, deadline_miss, bus_deadline, bus_error, no_odometry, unconfirmed, pending,
};
std::string_view to_string(MapReason r);

struct MapEntry {
    MapReason reason = MapReason::pending;
    bool has_tool = false;
    std::uint8_t tool = 0;
    std::uint8_t lane = 0;
    double fire_odom_mm = 0;
    GeorefResult georef;   // status off: no georef keys
    // Tool timing (sent only): the TARGET's fire_odom_mm as sent (32-bit
    // scale), the stem's point and the latency lead.
    std::uint32_t command_fire_raw = 0;
    double aim_odom_mm = 0;
    double lead_mm = 0;
    // Set when the tool's TOOL_FIRED came back.
    bool fired = false;
    double fired_odom_mm = 0;   // unwrapped, the map's scale
    double fire_lag_mm = 0;     // fired - commanded
    double fire_lag_ms = 0;     // NaN: standing
    double strike_mm = 0;       // fired - aim
};

class PlantMap {
public:
    explicit PlantMap(std::shared_ptr<spdlog::logger> log);
    PlantMap(const PlantMap&) = delete;
    PlantMap& operator=(const PlantMap&) = delete;

    // Creates (truncates) the file; false (logged with path and errno) if it cannot.
    bool open(const std::filesystem::path& path);
    bool is_open() const { return file_.is_open(); }

    // After open(): lines go through `writer` (which must outlive close()).
    void attach(RecordWriter& writer) { file_.attach(writer); }

    // One line; false if it was lost: it could not be queued (the writer's
    // ring full), or written (logged once). No allocation.
    bool write(const actuation::RetiredTrack& track, const MapEntry& entry);
    // Waits for the writer's last line of this file (at most
    // RecordWriter::kCloseTimeoutNs), then closes; false if anything was
    // lost. If the writer stalled, the file is left open (the writer thread
    // may be in a write(2) on it) and this map must not be destroyed:
    // output_stalled().
    bool close() { return file_.close(); }
    bool output_stalled() const { return file_.stalled(); }

    std::uint64_t lines() const { return lines_; }

private:
    RecordOutput file_;
    std::array<char, 768> line_{};   // one line: well under this
    static_assert(sizeof line_ <= RecordWriter::kLineBytes);
    std::uint64_t lines_ = 0;
};

}  // namespace stemd::runtime
