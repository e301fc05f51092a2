#include "stemd/runtime/gnss_input.hpp"

namespace stemd::runtime {

std::string_view to_string(GeorefStatus s)
{
    switch (s) {
    case GeorefStatus::off: return "off";
    case GeorefStatus::fix: return "fix";
    case GeorefStatus::extrapolated: return "extrapolated";
    case GeorefStatus::no_fix: return "no_fix";
    case GeorefStatus::stale: return "stale";
    case GeorefStatus::no_heading: return "no_heading";
    case GeorefStatus::degraded: return "degraded";
    }
    return "?";
}

bool has_position(GeorefStatus s)
{
    return s == GeorefStatus::fix || s == GeorefStatus::extrapolated || s == GeorefStatus::degraded;
}

namespace {

geometry::GnssTrackParams track_params(const GnssConfig& c)
{
    geometry::GnssTrackParams p;
    p.heading_baseline_mm = c.heading_baseline_mm;
    p.max_extrapolation_mm = c.max_extrapolation_mm;
    return p;
}

void bump(std::atomic<std::uint64_t>& c)
{
    c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

geometry::FixQuality quality_of(const drivers::GnssFix& fix)
{
    return {fix.mode, fix.quality, fix.eph_m < 0 ? -1.0 : fix.eph_m * 1e3};
}

}  // namespace

GnssInput::GnssInput(const GnssConfig& config, double principal_x_mm)
    : config_(config), principal_x_mm_(principal_x_mm), track_(track_params(config))
{
}

std::int64_t GnssInput::fix_time_ns(const drivers::GnssFix& fix, std::int64_t realtime_minus_monotonic_ns) const noexcept
{
    if (config_.time == GnssTime::gnss)
        return fix.gnss_time_ns - realtime_minus_monotonic_ns;
    return fix.timestamp_sample_ns;
}

bool GnssInput::try_place(const drivers::GnssFix& fix, const OdometryInput& odometry, std::int64_t now_ns,
                          std::int64_t realtime_minus_monotonic_ns) noexcept
{
    if (config_.time == GnssTime::gnss && fix.gnss_time_ns <= 0) {
        bump(unplaced_);   // a fix without its time (a receiver that has no date yet)
        return true;
    }
    const std::int64_t t_ns = fix_time_ns(fix, realtime_minus_monotonic_ns);
    if (!odometry.covers(t_ns)) {
        if (now_ns - t_ns <= config_.max_age_ns)
            return false;   // the odometer has not reached the fix's time yet
        bump(unplaced_);
        return true;
    }
    double odom_mm = 0;
    if (!odometry.odometer_at(t_ns, odom_mm)) {
        bump(unplaced_);
        return true;
    }
    const geometry::Geodetic g{fix.lat_deg, fix.lon_deg, fix.height_m};
    if (!plane_)
        plane_.emplace(g);
    const geometry::Enu p = plane_->to_enu(g);
    if (track_.add(odom_mm, p.e_m, p.n_m, t_ns, quality_of(fix)))
        bump(on_track_);
    else
        bump(unplaced_);
    return true;
}

void GnssInput::add(const drivers::GnssFix& fix, const OdometryInput& odometry, std::int64_t now_ns,
                    std::int64_t realtime_minus_monotonic_ns) noexcept
{
    bump(fixes_);
    last_mode_.store(fix.mode, std::memory_order_relaxed);
    last_status_.store(fix.quality, std::memory_order_relaxed);
    last_eph_mm_.store(quality_of(fix).eph_mm, std::memory_order_relaxed);
    // Fixes keep their order: one waits behind another.
    if (waiting_size_ == 0 && try_place(fix, odometry, now_ns, realtime_minus_monotonic_ns))
        return;
    if (waiting_size_ == waiting_.size()) {
        bump(unplaced_);   // the oldest waiting fix gives way
        waiting_head_ = (waiting_head_ + 1) % waiting_.size();
        --waiting_size_;
    }
    waiting_[(waiting_head_ + waiting_size_) % waiting_.size()] = fix;
    ++waiting_size_;
}

void GnssInput::poll(drivers::GnssSource& source, const OdometryInput& odometry, std::int64_t now_ns,
                     std::int64_t realtime_minus_monotonic_ns) noexcept
{
    while (waiting_size_ > 0 && try_place(waiting_[waiting_head_], odometry, now_ns, realtime_minus_monotonic_ns)) {
        waiting_head_ = (waiting_head_ + 1) % waiting_.size();
        --waiting_size_;
    }
    drivers::GnssFix fix;
    while (source.try_pop(fix))
        add(fix, odometry, now_ns, realtime_minus_monotonic_ns);
}

GeorefResult GnssInput::place(double s_mm, double y_mm, std::int64_t now_ns) noexcept
{
    GeorefResult r;
    r.status = GeorefStatus::no_fix;
    if (!plane_)
        return r;
    const geometry::PlacedPoint p = geometry::place_machine_point(track_, s_mm, principal_x_mm_, y_mm,
                                                                  config_.antenna_x_mm, config_.antenna_y_mm);
    r.quality = p.quality;
    const bool newest_is_old = track_.empty() || now_ns - track_.newest().t_ns > config_.max_age_ns;
    switch (p.status) {
    case geometry::TrackStatus::ok: r.status = GeorefStatus::fix; break;
    case geometry::TrackStatus::extrapolated:
        r.status = newest_is_old ? GeorefStatus::stale : GeorefStatus::extrapolated;
        break;
    case geometry::TrackStatus::beyond: r.status = newest_is_old ? GeorefStatus::stale : GeorefStatus::no_fix; break;
    case geometry::TrackStatus::no_heading: r.status = GeorefStatus::no_heading; break;
    case geometry::TrackStatus::before_history:
    case geometry::TrackStatus::empty: r.status = GeorefStatus::no_fix; break;
    }
    if (r.status != GeorefStatus::fix && r.status != GeorefStatus::extrapolated)
        return r;
    // An unknown estimate is not taken as a large one: the map line says
    // eph_mm null, and a receiver that reports none would otherwise never
    // place a plant.
    if (r.quality.eph_mm > config_.max_eph_mm) {
        r.status = GeorefStatus::degraded;
        bump(degraded_);
    }
    const geometry::Geodetic g = plane_->to_geodetic(p.enu);
    r.lat_deg = g.lat_deg;
    r.lon_deg = g.lon_deg;
    return r;
}

GnssCountersView GnssInput::counters() const
{
    GnssCountersView v;
    v.fixes = fixes_.load(std::memory_order_relaxed);
    v.on_track = on_track_.load(std::memory_order_relaxed);
    v.unplaced = unplaced_.load(std::memory_order_relaxed);
    v.degraded = degraded_.load(std::memory_order_relaxed);
    v.last = {last_mode_.load(std::memory_order_relaxed), last_status_.load(std::memory_order_relaxed),
              last_eph_mm_.load(std::memory_order_relaxed)};
    return v;
}

}  // namespace stemd::runtime
