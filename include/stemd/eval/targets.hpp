// Scoring the commands stemd sent against a field's ground truth: the
// TARGET frames of a candump log (stemd --can-log) against the plants of a
// moving recording (stemd-synth --strip writes plants.csv).
//
// A command is for the plant whose fire position it matches: its strike
// point should be s_mm + offset_mm of its tool. The strike point is not the
// commanded fire_odom_mm when the tool has a latency: stemd commands it
// speed × latency_ms earlier so that it strikes on the stem. It is the
// tool's TOOL_FIRED odometer when the log has one for the command, else
// fire_odom_mm + the lead (target_leads_mm); then it (compared modulo
// 2^18, as the TARGET carries it) and its lateral_mm the plant's y_mm.
// Matching is one-to-one, closest pairs first, within tol_mm (Euclidean in
// along/lateral error). A command within tol_mm of a plant that already has
// its match is a duplicate (the same plant commanded twice); a command near
// no plant is extra; a plant without a command is missed.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "stemd/protocol/messages.hpp"

namespace stemd::eval {

struct TruthPlant {
    long id = 0;
    double s_mm = 0;
    double y_mm = 0;
    PlantClass kind = PlantClass::Unknown;   // a word other than crop or weed: Unknown
    double radius_mm = 0;   // stem to the farthest leaf tip (optional column; 0 if absent)
};

// plants.csv: a header with at least id, s_mm, y_mm and kind columns (radius_mm optional).
// Errors name the file and line.
std::optional<std::vector<TruthPlant>> read_truth_plants(const std::filesystem::path& csv, std::string& error);

struct TargetLog {
    std::vector<protocol::TargetCommand> targets;   // in log order
    // Per target: the speed of the newest ODOMETRY frame before it (NaN:
    // none), and the odometer of the first TOOL_FIRED after it for the same
    // target and tool (NaN: none).
    std::vector<double> speed_mm_per_s;
    std::vector<double> fired_odom_mm;
    std::size_t other_frames = 0;    // HEARTBEAT and frames that are not stemd's
    std::size_t bad_targets = 0;     // TARGET identifier but failed decode (CRC, range)
};
// A candump -L log; errors (an unparsable line) name the file and line.
std::optional<TargetLog> read_target_log(const std::filesystem::path& log, const protocol::CanIds& ids,
                                         std::string& error);

struct TargetScore {
    std::size_t plants = 0;           // plants to be treated
    std::size_t commands = 0;
    std::size_t matched = 0;          // plants with a command within tol_mm
    std::size_t missed = 0;           // plants without one
    std::size_t duplicates = 0;       // second (third...) commands for a matched plant
    std::size_t extra = 0;            // commands near no plant
    std::size_t unknown_tool = 0;     // commands for a tool without an offset (counted as extra too)
    // Errors of the matched commands, mm: Euclidean, along-track, |lateral|.
    double error_p50_mm = 0, error_p95_mm = 0, error_max_mm = 0;
    double along_p50_mm = 0, lateral_p50_mm = 0;
    bool exact() const { return missed == 0 && duplicates == 0 && extra == 0; }
};

// Each target's strike point minus its fire_odom_mm, mm: its TOOL_FIRED's
// odometer minus fire_odom_mm (modulo 2^18) when the log has one, else
// speed × tool_latency_ms[tool_id] with the log's ODOMETRY speed before it,
// or default_speed_mm_per_s without one (stemd's odometry.speed_mm_per_s).
std::vector<double> target_leads_mm(const TargetLog& log, const std::array<double, 16>& tool_latency_ms,
                                    double default_speed_mm_per_s);

// tool_offset_mm[tool_id]: NaN for tools that do not exist. lead_mm: per
// command, added to its fire_odom_mm (target_leads_mm); empty: none.
TargetScore score_targets(std::span<const TruthPlant> plants, std::span<const protocol::TargetCommand> commands,
                          const std::array<double, 16>& tool_offset_mm, double tol_mm,
                          std::span<const double> lead_mm = {});

}  // namespace stemd::eval
