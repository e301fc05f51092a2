// The live view's JSON documents (/api/status, /api/plants, /api/config),
// built from plain values so that their shapes are tested without a server.
#pragma once

#include <deque>

#include <nlohmann/json.hpp>

#include "stemd/runtime/live_feed.hpp"
#include "stemd/runtime/status.hpp"
#include "stemd/web/metrics.hpp"

namespace stemd::web {

// /api/status: {"uptime_s", "frames_in", "frames_out", "stems", "late",
// "drops": {cause: n}, "actuation": null | {"targets", "sent", ...},
// "latency_ms"/"pipeline_ms"/"send_ms": {"p50", "p99", "max", "count"},
// "histograms": {name: {"le_ms": [...], "counts": [...] (per bucket, not
// cumulative; the last is beyond the last bound)}}, "live": {...}}.
nlohmann::json status_json(const runtime::StatusSnapshot& totals, const Metrics& metrics, double uptime_s);

// One plant as the plant map writes it: id, s_mm, y_mm, class, leaves,
// sightings, first_frame, last_frame, treated, reason and, with a tool,
// tool, lane, fire_odom_mm.
nlohmann::json plant_json(const runtime::LivePlant& plant);
// /api/plants: {"odom_mm": the latest frame's odometer or null, "plants": [oldest .. newest]}.
nlohmann::json plants_json(const std::deque<runtime::LivePlant>& plants, double odom_mm);

}  // namespace stemd::web
