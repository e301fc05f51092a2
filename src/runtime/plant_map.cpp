#include "stemd/runtime/plant_map.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>

namespace stemd::runtime {

namespace {

// The tool-timing columns (see plant_map.hpp) at line + n; the new length.
int append_fire_timing(char* line, std::size_t capacity, int n, const MapEntry& e)
{
    if (n < 0 || static_cast<std::size_t>(n) >= capacity || e.reason != MapReason::sent)
        return n;
    n += std::snprintf(line + n, capacity - static_cast<std::size_t>(n), ",\"fire_lead_mm\":%.1f", e.lead_mm);
    if (!e.fired || n < 0 || static_cast<std::size_t>(n) >= capacity)
        return n;
    char* const at = line + n;
    const std::size_t room = capacity - static_cast<std::size_t>(n);
    const int m = std::isfinite(e.fire_lag_ms)
        ? std::snprintf(at, room, ",\"fired_odom_mm\":%.1f,\"fire_lag_mm\":%.1f,\"fire_lag_ms\":%.1f,\"strike_mm\":%.1f",
                        e.fired_odom_mm, e.fire_lag_mm, e.fire_lag_ms, e.strike_mm)
        : std::snprintf(at, room, ",\"fired_odom_mm\":%.1f,\"fire_lag_mm\":%.1f,\"fire_lag_ms\":null,\"strike_mm\":%.1f",
                        e.fired_odom_mm, e.fire_lag_mm, e.strike_mm);
    return m < 0 ? m : n + m;
}

// The georef columns (see plant_map.hpp) at line + n; the new length.
int append_georef(char* line, std::size_t capacity, int n, const GeorefResult& g)
{
    if (n < 0 || static_cast<std::size_t>(n) >= capacity || g.status == GeorefStatus::off)
        return n;
    char* const at = line + n;
    const std::size_t room = capacity - static_cast<std::size_t>(n);
    const std::string_view status = to_string(g.status);
    const std::string_view mode = geometry::mode_name(g.quality.mode);
    const std::string_view fix = geometry::status_name(g.quality.status);
    char position[96];
    const int p = has_position(g.status)
        ? std::snprintf(position, sizeof position, "\"lat_deg\":%.9f,\"lon_deg\":%.9f", g.lat_deg, g.lon_deg)
        : std::snprintf(position, sizeof position, "\"lat_deg\":null,\"lon_deg\":null");
    if (p < 0 || static_cast<std::size_t>(p) >= sizeof position)
        return -1;   // not a latitude: never written cut
    char eph[32];
    if (g.quality.eph_mm >= 1e12)
        std::snprintf(eph, sizeof eph, "%.6g", g.quality.eph_mm);
    else if (g.quality.eph_mm >= 0)
        std::snprintf(eph, sizeof eph, "%.1f", g.quality.eph_mm);
    else
        std::snprintf(eph, sizeof eph, "null");
    const int m = std::snprintf(at, room, ",%s,\"georef\":\"%.*s\",\"gnss_mode\":\"%.*s\",\"gnss_status\":\"%.*s\",\"eph_mm\":%s",
                                position, static_cast<int>(status.size()), status.data(), static_cast<int>(mode.size()),
                                mode.data(), static_cast<int>(fix.size()), fix.data(), eph);
    return m < 0 ? m : n + m;
}

}  // namespace

std::string_view to_string(MapReason r)
{
    switch (r) {
    case MapReason::sent: return "sent";
    case MapReason::policy: return "policy";
    case MapReason::no_tool: return "no_tool";
    case MapReason::disabled: return "disabled";
    case MapReason::not_ready: return "not_ready";
    case MapReason::deadline_miss: return "deadline_miss";
    case MapReason::bus_deadline: return "bus_deadline";
    case MapReason::bus_error: return "bus_error";
    case MapReason::no_odometry: return "no_odometry";
    case MapReason::unconfirmed: return "unconfirmed";
    case MapReason::pending: return "pending";
    }
    return "?";
}

PlantMap::PlantMap(std::shared_ptr<spdlog::logger> log) : file_("plant map", std::move(log)) {}

bool PlantMap::open(const std::filesystem::path& path)
{
    return file_.open(path);
}

bool PlantMap::write(const actuation::RetiredTrack& t, const MapEntry& e)
{
    if (!file_.is_open())
        return true;
    const bool treated = e.reason == MapReason::sent;
    char* const line = line_.data();
    const std::size_t capacity = line_.size();
    int n = std::snprintf(line, capacity,
                          "{\"id\":%d,\"s_mm\":%.1f,\"y_mm\":%.1f,\"class\":\"%.*s\",\"leaves\":%u,\"sightings\":%u,"
                          "\"first_frame\":%llu,\"last_frame\":%llu,\"treated\":%s,\"reason\":\"%.*s\"",
                          t.emitted ? static_cast<int>(t.target_id) : -1, t.s_mm, t.y_mm,
                          static_cast<int>(to_string(t.plant_class).size()), to_string(t.plant_class).data(),
                          static_cast<unsigned>(t.leaves), static_cast<unsigned>(t.sightings),
                          static_cast<unsigned long long>(t.first_seq), static_cast<unsigned long long>(t.last_seq),
                          treated ? "true" : "false", static_cast<int>(to_string(e.reason).size()),
                          to_string(e.reason).data());
    if (n >= 0 && static_cast<std::size_t>(n) < capacity && e.has_tool)
        n += std::snprintf(line + n, capacity - static_cast<std::size_t>(n),
                           ",\"tool\":%u,\"lane\":%u,\"fire_odom_mm\":%.1f", static_cast<unsigned>(e.tool),
                           static_cast<unsigned>(e.lane), e.fire_odom_mm);
    n = append_fire_timing(line, capacity, n, e);
    n = append_georef(line, capacity, n, e.georef);
    if (n >= 0 && static_cast<std::size_t>(n) < capacity)
        n += std::snprintf(line + n, capacity - static_cast<std::size_t>(n), "}\n");
    if (n < 0 || static_cast<std::size_t>(n) >= capacity)
        return file_.lose(EOVERFLOW);   // a 1e300 position would not fit: never written half
    if (!file_.write({line, static_cast<std::size_t>(n)}))
        return false;
    ++lines_;
    return true;
}

}  // namespace stemd::runtime
