// Georeferencing: from the odometer's field coordinates to WGS84, with a
// GNSS antenna on the machine. Pure functions and one fixed-capacity track;
// nothing here allocates after construction, locks or does I/O.
//
// Frames:
//  - WGS84 geodetic: latitude, longitude (degrees), height above the
//    ellipsoid (metres).
//  - A local tangent plane (ENU: east, north, up, metres) around an origin,
//    usually the first fix: flat enough over a field (the curvature drops
//    2 mm below the plane 160 m from the origin, and the conversion back is
//    exact, not a flat-earth approximation).
//  - The machine frame (README, "Machine frame and field coordinates"):
//    x forward, y left, millimetres. Its heading is the angle of machine x
//    in the ENU plane, counter-clockwise from east, radians.
//
// The track (GnssTrack) keys each antenna position by the odometer at the
// fix's time, so that a plant's along-track field coordinate s_mm finds
// its position between the fixes bracketing it, whatever the speed; the
// heading comes from the track itself (the direction of motion over a
// minimum travelled distance), so standing still does not make it noisy.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>

namespace stemd::geometry {

struct Geodetic {
    double lat_deg = 0;
    double lon_deg = 0;
    double height_m = 0;   // above the WGS84 ellipsoid
};

struct Ecef {
    double x_m = 0;
    double y_m = 0;
    double z_m = 0;
};

struct Enu {
    double e_m = 0;
    double n_m = 0;
    double u_m = 0;
};

// WGS84 geodetic <-> earth-centred earth-fixed.
Ecef geodetic_to_ecef(const Geodetic& g) noexcept;
// Iterative (converges to well below a millimetre in a few steps anywhere
// outside the earth's core).
Geodetic ecef_to_geodetic(const Ecef& p) noexcept;

// A local tangent plane (east, north, up) at `origin`.
class LocalTangentPlane {
public:
    explicit LocalTangentPlane(const Geodetic& origin) noexcept;
    Enu to_enu(const Geodetic& g) const noexcept;
    Geodetic to_geodetic(const Enu& p) const noexcept;
    const Geodetic& origin() const { return origin_; }

private:
    Geodetic origin_;
    Ecef origin_ecef_;
    double sin_lat_, cos_lat_, sin_lon_, cos_lon_;
};

// A machine-frame vector (x forward, y left; mm) in the ENU plane (m), the
// machine heading `heading_rad` (machine x counter-clockwise from east).
struct PlaneOffset {
    double e_m = 0;
    double n_m = 0;
};
PlaneOffset machine_to_enu(double x_mm, double y_mm, double heading_rad) noexcept;

// The heading of a displacement in the ENU plane (counter-clockwise from
// east, radians, in (-pi, pi]).
double heading_of(double de_m, double dn_m) noexcept;

// A fix's quality as the receiver reports it: gpsd's fix mode and status,
// and its horizontal error estimate.
struct FixQuality {
    std::uint8_t mode = 0;     // 0, 1: no fix; 2: 2D; 3: 3D
    std::uint8_t status = 0;   // gpsd: 0 unknown, 1 GPS, 2 DGPS, 3 RTK fixed, 4 RTK float, 5 DR, 6 GNSS+DR, 7 time, 8 simulated, 9 PPS
    double eph_mm = -1;        // horizontal error estimate (95 %); < 0: unknown
};
// The lesser of two fixes' qualities, part by part: the lower mode, the
// larger error (unknown if either is), the less precise status. A position
// made from two fixes is no better than the worse one.
FixQuality worse(const FixQuality& a, const FixQuality& b) noexcept;
// "none", "2d", "3d".
std::string_view mode_name(std::uint8_t mode);
// "none", "gps", "dgps", "rtk_fixed", "rtk_float", "dr", "gnss_dr", "time", "sim", "pps".
std::string_view status_name(std::uint8_t status);

// One antenna position on the track: the odometer at the fix's time and the
// fix's position in the plane.
struct TrackPoint {
    double odom_mm = 0;
    double e_m = 0;
    double n_m = 0;
    std::int64_t t_ns = 0;   // the fix's time (CLOCK_MONOTONIC)
    std::uint32_t fixes = 1; // fixes averaged into this point (standing still)
    FixQuality quality;      // the worst of those fixes'
};

enum class TrackStatus : std::uint8_t {
    ok,             // between two points (or on one)
    extrapolated,   // past the newest point along the heading, within max_extrapolation_mm
    beyond,         // past the newest point by more than that
    before_history, // before the oldest point kept
    empty,          // no point (yet)
    no_heading,     // extrapolation needs a heading the track does not give
};
std::string_view to_string(TrackStatus s);

struct TrackQuery {
    TrackStatus status = TrackStatus::empty;
    double e_m = 0;
    double n_m = 0;
    // The fixes the position came from: the worse of the two bracketing it,
    // or the newest when past it. Default (mode 0) when the track is empty
    // or the query is before its history.
    FixQuality quality;
};

struct GnssTrackParams {
    std::size_t capacity = 4096;          // points kept (at least 2)
    // Fixes closer than this along the odometer are averaged into one point:
    // a machine standing still accumulates one point, not a noisy cloud.
    double min_step_mm = 5;
    // The heading is the direction between the track's positions this far
    // apart along the odometer (centred on the query where it can be).
    double heading_baseline_mm = 1000;
    // How far past the newest point a position may be extrapolated.
    double max_extrapolation_mm = 500;
};

class GnssTrack {
public:
    explicit GnssTrack(const GnssTrackParams& params = {});

    // Adds a fix's antenna position at odometer odom_mm. Refused (false)
    // when not finite or the odometer ran back. When full, the oldest point
    // is overwritten.
    bool add(double odom_mm, double e_m, double n_m, std::int64_t t_ns, const FixQuality& quality = {}) noexcept;

    // The antenna position when the odometer read odom_mm.
    TrackQuery position_at(double odom_mm) const noexcept;
    // The heading around odom_mm from heading_baseline_mm of travel; nullopt
    // when the track holds less travel than that or the travel is too
    // short in the plane (less than half the baseline: the fixes disagree
    // with the odometer).
    std::optional<double> heading_at(double odom_mm) const noexcept;

    std::size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    const TrackPoint& at(std::size_t i) const { return points_[(head_ + i) % capacity_]; }
    const TrackPoint& newest() const { return at(size_ - 1); }
    const TrackPoint& oldest() const { return at(0); }
    const GnssTrackParams& params() const { return params_; }

private:
    // Linear between the points around odom_mm (which must be within them);
    // quality, when given, gets the worse of those points'.
    void interpolate(double odom_mm, double& e_m, double& n_m, FixQuality* quality = nullptr) const noexcept;

    GnssTrackParams params_;
    std::size_t capacity_;
    std::unique_ptr<TrackPoint[]> points_;
    std::size_t head_ = 0;
    std::size_t size_ = 0;
};

// Where a machine-frame point (x_mm, y_mm) was when the odometer read
// odom_mm, from the antenna's track and the antenna's machine-frame
// position: antenna + R(heading) * (point - antenna).
struct PlacedPoint {
    TrackStatus status = TrackStatus::empty;
    Enu enu;
    FixQuality quality;   // the antenna position's (TrackQuery::quality)
};
PlacedPoint place_machine_point(const GnssTrack& track, double odom_mm, double x_mm, double y_mm,
                                double antenna_x_mm, double antenna_y_mm) noexcept;

}  // namespace stemd::geometry
