#include "stemd/web/web_json.hpp"

#include <cmath>

namespace stemd::web {

namespace {

nlohmann::json summary_json(const runtime::DurationHistogram::Summary& s)
{
    return {{"p50", s.p50_ms}, {"p99", s.p99_ms}, {"max", s.max_ms}, {"count", s.count}};
}

nlohmann::json histogram_json(const Histogram& h)
{
    nlohmann::json le = nlohmann::json::array(), counts = nlohmann::json::array();
    std::uint64_t below = 0;
    for (std::size_t i = 0; i < kBucketUpperNs.size(); ++i) {
        le.push_back(static_cast<double>(kBucketUpperNs[i]) / 1e6);
        counts.push_back(h.below[i] - below);
        below = h.below[i];
    }
    counts.push_back(h.count - below);
    return {{"le_ms", le}, {"counts", counts}, {"count", h.count}, {"sum_s", h.sum_s}};
}

}  // namespace

nlohmann::json status_json(const runtime::StatusSnapshot& s, const Metrics& m, double uptime_s)
{
    nlohmann::json j;
    j["uptime_s"] = uptime_s;
    j["frames_in"] = s.frames_in;
    j["frames_out"] = s.frames_out;
    j["stems"] = s.stems_out;
    j["late"] = s.late;
    j["no_vegetation"] = s.no_vegetation;
    j["drops"] = {{"ring_full", s.ring_full}, {"overwritten", s.overwritten}, {"results_full", s.results_full},
                  {"corrupt", s.corrupt},     {"bad_size", s.bad_size},       {"failed", s.failed}};
    if (s.actuation)
        j["actuation"] = {{"targets", m.targets},       {"sent", m.sent},
                          {"policy", m.policy},         {"no_tool", m.no_tool},
                          {"disabled", m.disabled},     {"not_ready", m.not_ready},
                          {"deadline_miss", m.deadline_miss},
                          {"bus_deadline", m.bus_deadline}, {"bus_errors", m.bus_error},
                          {"heartbeat_errors", m.heartbeat_errors}, {"heartbeat_misses", m.heartbeat_misses},
                          {"no_odometry", m.no_odometry}};
    else
        j["actuation"] = nullptr;
    j["trigger"] = s.trigger ? nlohmann::json{{"pulses", s.trigger_pulses},
                                              {"late", s.trigger_late},
                                              {"failed", s.trigger_failed}}
                             : nlohmann::json(nullptr);
    j["files"] = s.files ? nlohmann::json{{"lines_written", s.file_lines_written}, {"lines_lost", s.file_lines_lost}}
                         : nlohmann::json(nullptr);
    j["latency_ms"] = summary_json(s.latency);
    j["pipeline_ms"] = summary_json(s.pipeline);
    j["send_ms"] = summary_json(s.send);
    j["histograms"] = {{"capture_to_result", histogram_json(m.capture_to_result)},
                       {"capture_to_send", histogram_json(m.capture_to_send)},
                       {"pipeline", histogram_json(m.pipeline)}};
    j["live"] = {{"frames_published", m.live_frames_published},
                 {"frames_encoded", m.live_frames_encoded},
                 {"plants_dropped", m.live_plants_dropped},
                 {"requests", m.web_requests},
                 {"unauthorized", m.web_unauthorized}};
    return j;
}

nlohmann::json plant_json(const runtime::LivePlant& p)
{
    nlohmann::json j = {{"id", p.id},
                        {"s_mm", p.s_mm},
                        {"y_mm", p.y_mm},
                        {"class", std::string(to_string(p.plant_class))},
                        {"leaves", p.leaves},
                        {"sightings", p.sightings},
                        {"first_frame", p.first_frame},
                        {"last_frame", p.last_frame},
                        {"treated", p.entry.reason == runtime::MapReason::sent},
                        {"reason", std::string(runtime::to_string(p.entry.reason))}};
    if (p.entry.has_tool) {
        j["tool"] = p.entry.tool;
        j["lane"] = p.entry.lane;
        j["fire_odom_mm"] = p.entry.fire_odom_mm;
    }
    return j;
}

nlohmann::json plants_json(const std::deque<runtime::LivePlant>& plants, double odom_mm)
{
    nlohmann::json list = nlohmann::json::array();
    for (const runtime::LivePlant& p : plants)
        list.push_back(plant_json(p));
    return {{"odom_mm", std::isfinite(odom_mm) ? nlohmann::json(odom_mm) : nlohmann::json(nullptr)},
            {"plants", std::move(list)}};
}

}  // namespace stemd::web
