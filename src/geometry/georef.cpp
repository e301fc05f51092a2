#include "stemd/geometry/georef.hpp"

#include <algorithm>
#include <cmath>

namespace stemd::geometry {

namespace {

// WGS84 (NIMA TR8350.2).
constexpr double kA = 6378137.0;
constexpr double kF = 1.0 / 298.257223563;
constexpr double kE2 = kF * (2 - kF);
constexpr double kDegToRad = M_PI / 180.0;

double prime_vertical_radius(double sin_lat) noexcept
{
    return kA / std::sqrt(1 - kE2 * sin_lat * sin_lat);
}

}  // namespace

Ecef geodetic_to_ecef(const Geodetic& g) noexcept
{
    const double lat = g.lat_deg * kDegToRad;
    const double lon = g.lon_deg * kDegToRad;
    const double n = prime_vertical_radius(std::sin(lat));
    return {(n + g.height_m) * std::cos(lat) * std::cos(lon), (n + g.height_m) * std::cos(lat) * std::sin(lon),
            (n * (1 - kE2) + g.height_m) * std::sin(lat)};
}

Geodetic ecef_to_geodetic(const Ecef& e) noexcept
{
    const double p = std::hypot(e.x_m, e.y_m);
    const double lon = std::atan2(e.y_m, e.x_m);
    double lat = std::atan2(e.z_m, p * (1 - kE2));
    double h = 0;
    // Fixed-point iteration on the latitude; the height from the form that
    // stays finite at the poles (no division by cos(lat)).
    for (int i = 0; i < 8; ++i) {
        const double s = std::sin(lat);
        const double n = prime_vertical_radius(s);
        h = p * std::cos(lat) + e.z_m * s - kA * std::sqrt(1 - kE2 * s * s);
        lat = std::atan2(e.z_m, p * (1 - kE2 * n / (n + h)));
    }
    const double s = std::sin(lat);
    h = p * std::cos(lat) + e.z_m * s - kA * std::sqrt(1 - kE2 * s * s);
    return {lat / kDegToRad, lon / kDegToRad, h};
}

LocalTangentPlane::LocalTangentPlane(const Geodetic& origin) noexcept
    : origin_(origin),
      origin_ecef_(geodetic_to_ecef(origin)),
      sin_lat_(std::sin(origin.lat_deg * kDegToRad)),
      cos_lat_(std::cos(origin.lat_deg * kDegToRad)),
      sin_lon_(std::sin(origin.lon_deg * kDegToRad)),
      cos_lon_(std::cos(origin.lon_deg * kDegToRad))
{
}

Enu LocalTangentPlane::to_enu(const Geodetic& g) const noexcept
{
    const Ecef p = geodetic_to_ecef(g);
    const double dx = p.x_m - origin_ecef_.x_m;
    const double dy = p.y_m - origin_ecef_.y_m;
    const double dz = p.z_m - origin_ecef_.z_m;
    return {-sin_lon_ * dx + cos_lon_ * dy,
            -sin_lat_ * cos_lon_ * dx - sin_lat_ * sin_lon_ * dy + cos_lat_ * dz,
            cos_lat_ * cos_lon_ * dx + cos_lat_ * sin_lon_ * dy + sin_lat_ * dz};
}

Geodetic LocalTangentPlane::to_geodetic(const Enu& p) const noexcept
{
    const Ecef e{origin_ecef_.x_m - sin_lon_ * p.e_m - sin_lat_ * cos_lon_ * p.n_m + cos_lat_ * cos_lon_ * p.u_m,
                 origin_ecef_.y_m + cos_lon_ * p.e_m - sin_lat_ * sin_lon_ * p.n_m + cos_lat_ * sin_lon_ * p.u_m,
                 origin_ecef_.z_m + cos_lat_ * p.n_m + sin_lat_ * p.u_m};
    return ecef_to_geodetic(e);
}

PlaneOffset machine_to_enu(double x_mm, double y_mm, double heading_rad) noexcept
{
    // Machine y is 90 degrees counter-clockwise from machine x (left).
    const double c = std::cos(heading_rad);
    const double s = std::sin(heading_rad);
    return {(x_mm * c - y_mm * s) * 1e-3, (x_mm * s + y_mm * c) * 1e-3};
}

double heading_of(double de_m, double dn_m) noexcept
{
    return std::atan2(dn_m, de_m);
}

std::string_view to_string(TrackStatus s)
{
    switch (s) {
    case TrackStatus::ok: return "ok";
    case TrackStatus::extrapolated: return "extrapolated";
    case TrackStatus::beyond: return "beyond";
    case TrackStatus::before_history: return "before_history";
    case TrackStatus::empty: return "empty";
    case TrackStatus::no_heading: return "no_heading";
    }
    return "?";
}

namespace {

// How precise a gpsd fix status is: lower is better. Dead reckoning,
// time-only, simulated and unknown come after any satellite position.
int status_rank(std::uint8_t status)
{
    switch (status) {
    case 3: return 0;   // RTK fixed
    case 4: return 1;   // RTK float
    case 2: return 2;   // DGPS
    case 1: return 3;   // GPS
    case 9: return 3;   // PPS: a GPS fix with a disciplined time
    case 6: return 4;   // GNSS + dead reckoning
    case 5: return 5;   // dead reckoning alone
    default: return 6;  // unknown, time only, simulated
    }
}

}  // namespace

FixQuality worse(const FixQuality& a, const FixQuality& b) noexcept
{
    FixQuality w;
    w.mode = std::min(a.mode, b.mode);
    w.status = status_rank(a.status) >= status_rank(b.status) ? a.status : b.status;
    w.eph_mm = a.eph_mm < 0 || b.eph_mm < 0 ? -1 : std::max(a.eph_mm, b.eph_mm);
    return w;
}

std::string_view mode_name(std::uint8_t mode)
{
    switch (mode) {
    case 2: return "2d";
    case 3: return "3d";
    default: return "none";
    }
}

std::string_view status_name(std::uint8_t status)
{
    switch (status) {
    case 1: return "gps";
    case 2: return "dgps";
    case 3: return "rtk_fixed";
    case 4: return "rtk_float";
    case 5: return "dr";
    case 6: return "gnss_dr";
    case 7: return "time";
    case 8: return "sim";
    case 9: return "pps";
    default: return "none";
    }
}

GnssTrack::GnssTrack(const GnssTrackParams& params)
    : params_(params), capacity_(std::max<std::size_t>(params.capacity, 2)), points_(new TrackPoint[capacity_])
{
}

bool GnssTrack::add(double odom_mm, double e_m, double n_m, std::int64_t t_ns, const FixQuality& quality) noexcept
{
    if (!std::isfinite(odom_mm) || !std::isfinite(e_m) || !std::isfinite(n_m))
        return false;
    if (size_ > 0) {
        TrackPoint& last = points_[(head_ + size_ - 1) % capacity_];
        if (odom_mm < last.odom_mm)
            return false;
        if (odom_mm - last.odom_mm < params_.min_step_mm) {
            // The running mean of the fixes (odometer too, so that a slow
            // machine's point stays where its fixes were).
            const double k = static_cast<double>(last.fixes);
            last.e_m = (last.e_m * k + e_m) / (k + 1);
            last.n_m = (last.n_m * k + n_m) / (k + 1);
            last.odom_mm = std::max(last.odom_mm, (last.odom_mm * k + odom_mm) / (k + 1));
            last.t_ns = t_ns;
            last.quality = worse(last.quality, quality);
            ++last.fixes;
            return true;
        }
    }
    if (size_ == capacity_) {
        head_ = (head_ + 1) % capacity_;
        --size_;
    }
    points_[(head_ + size_) % capacity_] = {odom_mm, e_m, n_m, t_ns, 1, quality};
    ++size_;
    return true;
}

void GnssTrack::interpolate(double odom_mm, double& e_m, double& n_m, FixQuality* quality) const noexcept
{
    // The last point at or before odom_mm (binary search over the ring).
    std::size_t lo = 0;
    std::size_t hi = size_ - 1;
    while (lo < hi) {
        const std::size_t mid = (lo + hi + 1) / 2;
        if (at(mid).odom_mm <= odom_mm)
            lo = mid;
        else
            hi = mid - 1;
    }
    const TrackPoint& a = at(lo);
    if (lo + 1 >= size_ || odom_mm <= a.odom_mm) {
        e_m = a.e_m;
        n_m = a.n_m;
        if (quality != nullptr)
            *quality = a.quality;
        return;
    }
    const TrackPoint& b = at(lo + 1);
    if (quality != nullptr)
        *quality = worse(a.quality, b.quality);
    const double f = (odom_mm - a.odom_mm) / (b.odom_mm - a.odom_mm);
    e_m = a.e_m + f * (b.e_m - a.e_m);
    n_m = a.n_m + f * (b.n_m - a.n_m);
}

TrackQuery GnssTrack::position_at(double odom_mm) const noexcept
{
    TrackQuery q;
    if (size_ == 0 || !std::isfinite(odom_mm))
        return q;
    if (odom_mm < oldest().odom_mm) {
        q.status = TrackStatus::before_history;
        return q;
    }
    if (odom_mm <= newest().odom_mm) {
        q.status = TrackStatus::ok;
        interpolate(odom_mm, q.e_m, q.n_m, &q.quality);
        return q;
    }
    const double ahead_mm = odom_mm - newest().odom_mm;
    q.e_m = newest().e_m;
    q.n_m = newest().n_m;
    q.quality = newest().quality;
    if (ahead_mm > params_.max_extrapolation_mm) {
        q.status = TrackStatus::beyond;
        return q;
    }
    const auto heading = heading_at(newest().odom_mm);
    if (!heading) {
        q.status = TrackStatus::no_heading;
        return q;
    }
    const PlaneOffset d = machine_to_enu(ahead_mm, 0, *heading);
    q.status = TrackStatus::extrapolated;
    q.e_m += d.e_m;
    q.n_m += d.n_m;
    return q;
}

std::optional<double> GnssTrack::heading_at(double odom_mm) const noexcept
{
    const double baseline = params_.heading_baseline_mm;
    if (size_ < 2 || !std::isfinite(odom_mm) || newest().odom_mm - oldest().odom_mm < baseline)
        return std::nullopt;
    // Centred on the query, shifted inside the track near its ends.
    const double lo = std::clamp(odom_mm - baseline / 2, oldest().odom_mm, newest().odom_mm - baseline);
    double e0 = 0, n0 = 0, e1 = 0, n1 = 0;
    interpolate(lo, e0, n0);
    interpolate(lo + baseline, e1, n1);
    if (std::hypot(e1 - e0, n1 - n0) < 0.5 * baseline * 1e-3)
        return std::nullopt;
    return heading_of(e1 - e0, n1 - n0);
}

PlacedPoint place_machine_point(const GnssTrack& track, double odom_mm, double x_mm, double y_mm,
                                double antenna_x_mm, double antenna_y_mm) noexcept
{
    PlacedPoint out;
    const TrackQuery antenna = track.position_at(odom_mm);
    out.status = antenna.status;
    out.quality = antenna.quality;
    if (antenna.status != TrackStatus::ok && antenna.status != TrackStatus::extrapolated)
        return out;
    out.enu = {antenna.e_m, antenna.n_m, 0};
    if (x_mm == antenna_x_mm && y_mm == antenna_y_mm)
        return out;   // the antenna itself: no heading needed
    const auto heading = track.heading_at(odom_mm);
    if (!heading) {
        out.status = TrackStatus::no_heading;
        return out;
    }
    const PlaneOffset d = machine_to_enu(x_mm - antenna_x_mm, y_mm - antenna_y_mm, *heading);
    out.enu.e_m += d.e_m;
    out.enu.n_m += d.n_m;
    return out;
}

}  // namespace stemd::geometry
