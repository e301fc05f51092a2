// Georeferencing: WGS84 <-> ECEF <-> local tangent plane against published
// values, and the odometer-keyed GNSS track (interpolation, heading, standing
// still, extrapolation bounds, the antenna offset).
#include <gtest/gtest.h>

#include <cmath>

#include "stemd/geometry/georef.hpp"

using namespace stemd::geometry;

namespace {

constexpr double kPi = 3.14159265358979323846;

// A track heading `heading_rad` from (0, 0), one fix every `step_mm` of
// odometer from 0 to `length_mm`.
GnssTrack straight_track(double heading_rad, double step_mm, double length_mm, const GnssTrackParams& p = {})
{
    GnssTrack track(p);
    for (double s = 0; s <= length_mm; s += step_mm)
        track.add(s, s * 1e-3 * std::cos(heading_rad), s * 1e-3 * std::sin(heading_rad),
                  static_cast<std::int64_t>(s * 1e6));
    return track;
}

}  // namespace

TEST(Georef, EcefOfKnownPoints)
{
    // On the equator at the prime meridian: the semi-major axis.
    const Ecef a = geodetic_to_ecef({0, 0, 0});
    EXPECT_NEAR(a.x_m, 6378137.0, 1e-6);
    EXPECT_NEAR(a.y_m, 0, 1e-6);
    EXPECT_NEAR(a.z_m, 0, 1e-6);
    // The north pole: the semi-minor axis b = 6356752.314245 m (WGS84).
    const Ecef b = geodetic_to_ecef({90, 0, 0});
    EXPECT_NEAR(b.z_m, 6356752.314245, 1e-5);
    EXPECT_NEAR(std::hypot(b.x_m, b.y_m), 0, 1e-6);
    // 90 degrees east, 100 m up.
    const Ecef c = geodetic_to_ecef({0, 90, 100});
    EXPECT_NEAR(c.y_m, 6378237.0, 1e-6);
}

TEST(Georef, EcefRoundTripIsExactToAMicrometre)
{
    for (const Geodetic g : {Geodetic{51.4858, 7.4108, 120.5}, Geodetic{-33.9, 151.2, -20}, Geodetic{0, 0, 0},
                             Geodetic{89.9, -179.5, 3000}, Geodetic{50.7, 7.1, 60}}) {
        const Geodetic back = ecef_to_geodetic(geodetic_to_ecef(g));
        EXPECT_NEAR(back.lat_deg, g.lat_deg, 1e-11);
        EXPECT_NEAR(back.lon_deg, g.lon_deg, 1e-11);
        EXPECT_NEAR(back.height_m, g.height_m, 1e-6);
    }
}

TEST(Georef, TangentPlaneMatchesTheLengthOfADegree)
{
    // The lengths of one degree (Wikipedia, "Latitude", from WGS84): at the
    // equator 110 574 m of latitude and 111 320 m of longitude; at 45
    // degrees 111 132 m and 78 847 m. Rounded to the metre: 1 mm on 0.001 degree.
    struct Case { double lat, m_per_deg_lat, m_per_deg_lon; };
    for (const Case c : {Case{0, 110574, 111320}, Case{45, 111132, 78847}}) {
        const LocalTangentPlane ltp({c.lat, 10, 0});
        const Enu north = ltp.to_enu({c.lat + 0.0005, 10, 0});
        const Enu south = ltp.to_enu({c.lat - 0.0005, 10, 0});
        EXPECT_NEAR(north.n_m - south.n_m, c.m_per_deg_lat * 0.001, 0.002) << c.lat;
        EXPECT_NEAR(north.e_m, 0, 1e-6);
        const Enu east = ltp.to_enu({c.lat, 10.0005, 0});
        const Enu west = ltp.to_enu({c.lat, 9.9995, 0});
        EXPECT_NEAR(east.e_m - west.e_m, c.m_per_deg_lon * 0.001, 0.002) << c.lat;
    }
}

TEST(Georef, TangentPlaneRoundTripAndOrigin)
{
    const LocalTangentPlane ltp({50.7, 7.1, 60});
    const Enu o = ltp.to_enu({50.7, 7.1, 60});
    EXPECT_NEAR(o.e_m, 0, 1e-9);
    EXPECT_NEAR(o.n_m, 0, 1e-9);
    EXPECT_NEAR(o.u_m, 0, 1e-9);
    for (const Enu p : {Enu{12.5, -3.25, 0}, Enu{-800, 1500, 2}, Enu{0.001, 0.002, 0}}) {
        const Geodetic g = ltp.to_geodetic(p);
        const Enu back = ltp.to_enu(g);
        EXPECT_NEAR(back.e_m, p.e_m, 1e-6);
        EXPECT_NEAR(back.n_m, p.n_m, 1e-6);
        EXPECT_NEAR(back.u_m, p.u_m, 1e-6);
    }
    // Up is up: a point straight above the origin.
    const Enu up = ltp.to_enu({50.7, 7.1, 70});
    EXPECT_NEAR(up.u_m, 10, 1e-6);
    EXPECT_NEAR(std::hypot(up.e_m, up.n_m), 0, 1e-6);
}

TEST(Georef, MachineVectorsRotateWithTheHeading)
{
    // Heading east: forward is east, left is north.
    PlaneOffset d = machine_to_enu(1000, 0, 0);
    EXPECT_NEAR(d.e_m, 1, 1e-12);
    EXPECT_NEAR(d.n_m, 0, 1e-12);
    d = machine_to_enu(0, 1000, 0);
    EXPECT_NEAR(d.e_m, 0, 1e-12);
    EXPECT_NEAR(d.n_m, 1, 1e-12);
    // Heading north: left is west.
    d = machine_to_enu(0, 1000, kPi / 2);
    EXPECT_NEAR(d.e_m, -1, 1e-12);
    EXPECT_NEAR(d.n_m, 0, 1e-12);
    EXPECT_NEAR(heading_of(0, 1), kPi / 2, 1e-12);
    EXPECT_NEAR(heading_of(-1, 0), kPi, 1e-12);
}

TEST(Georef, TrackInterpolatesByOdometer)
{
    const GnssTrack track = straight_track(kPi / 6, 100, 10000);
    const TrackQuery q = track.position_at(2550);
    ASSERT_EQ(q.status, TrackStatus::ok);
    EXPECT_NEAR(q.e_m, 2.55 * std::cos(kPi / 6), 1e-9);
    EXPECT_NEAR(q.n_m, 2.55 * std::sin(kPi / 6), 1e-9);
    const auto h = track.heading_at(5000);
    ASSERT_TRUE(h);
    EXPECT_NEAR(*h, kPi / 6, 1e-9);
    // Near the ends the baseline shifts inside the track.
    ASSERT_TRUE(track.heading_at(0));
    ASSERT_TRUE(track.heading_at(10000));
}

TEST(Georef, TrackStatusesAtItsEdges)
{
    GnssTrackParams p;
    p.max_extrapolation_mm = 300;
    const GnssTrack empty(p);
    EXPECT_EQ(empty.position_at(0).status, TrackStatus::empty);
    EXPECT_FALSE(empty.heading_at(0));

    GnssTrack track(p);
    for (double s = 1000; s <= 3000; s += 100)
        track.add(s, 0, s * 1e-3, 0);   // heading north
    EXPECT_EQ(track.position_at(999).status, TrackStatus::before_history);
    const TrackQuery ahead = track.position_at(3200);
    ASSERT_EQ(ahead.status, TrackStatus::extrapolated);
    EXPECT_NEAR(ahead.e_m, 0, 1e-9);
    EXPECT_NEAR(ahead.n_m, 3.2, 1e-9);
    EXPECT_EQ(track.position_at(3301).status, TrackStatus::beyond);
    // Less travel than the heading baseline: no heading, no extrapolation.
    GnssTrack short_track(p);
    short_track.add(0, 0, 0, 0);
    short_track.add(500, 0, 0.5, 0);
    EXPECT_FALSE(short_track.heading_at(250));
    EXPECT_EQ(short_track.position_at(600).status, TrackStatus::no_heading);
    EXPECT_EQ(short_track.position_at(250).status, TrackStatus::ok);
}

TEST(Georef, TrackRefusesAnOdometerRunningBackAndNonFiniteValues)
{
    GnssTrack track;
    EXPECT_TRUE(track.add(100, 0, 0, 0));
    EXPECT_FALSE(track.add(50, 1, 1, 0));
    EXPECT_FALSE(track.add(NAN, 1, 1, 0));
    EXPECT_FALSE(track.add(200, INFINITY, 1, 0));
    EXPECT_EQ(track.size(), 1u);
}

TEST(Georef, StandingStillAveragesTheFixesAndKeepsTheHeading)
{
    GnssTrack track = straight_track(0, 100, 3000);   // heading east, to e = 3 m
    const std::size_t before = track.size();
    // Stand at odometer 3000 for 100 fixes scattered +-2 cm north and south.
    for (int i = 0; i < 100; ++i)
        track.add(3000, 3.0, (i % 2 == 0 ? 0.02 : -0.02), 0);
    EXPECT_EQ(track.size(), before);
    EXPECT_EQ(track.newest().fixes, 101u);
    EXPECT_NEAR(track.newest().n_m, 0, 1e-3);
    const auto h = track.heading_at(3000);
    ASSERT_TRUE(h);
    EXPECT_NEAR(*h, 0, 1e-3);
}

TEST(Georef, TrackOverwritesItsOldestPointWhenFull)
{
    GnssTrackParams p;
    p.capacity = 4;
    GnssTrack track(p);
    for (int i = 0; i < 6; ++i)
        track.add(i * 100.0, i * 0.1, 0, i);
    EXPECT_EQ(track.size(), 4u);
    EXPECT_EQ(track.oldest().odom_mm, 200);
    EXPECT_EQ(track.newest().odom_mm, 500);
    EXPECT_EQ(track.position_at(150).status, TrackStatus::before_history);
}

TEST(Georef, PlacesAMachinePointFromTheAntenna)
{
    // Heading north; the antenna 1000 mm ahead of the machine origin and
    // 200 mm left; the point 300 mm right of the origin: 500 mm east of the
    // antenna and 1000 mm behind it (south).
    const GnssTrack track = straight_track(kPi / 2, 100, 5000);
    const PlacedPoint p = place_machine_point(track, 2000, 0, -300, 1000, 200);
    ASSERT_EQ(p.status, TrackStatus::ok);
    EXPECT_NEAR(p.enu.e_m, 0.5, 1e-9);
    EXPECT_NEAR(p.enu.n_m, 2.0 - 1.0, 1e-9);
    // The antenna itself needs no heading.
    GnssTrack one;
    one.add(0, 4, 5, 0);
    const PlacedPoint a = place_machine_point(one, 0, 10, 20, 10, 20);
    ASSERT_EQ(a.status, TrackStatus::ok);
    EXPECT_NEAR(a.enu.e_m, 4, 1e-12);
    EXPECT_EQ(place_machine_point(one, 0, 0, 0, 10, 20).status, TrackStatus::no_heading);
}

TEST(GnssTrack, AQueryCarriesTheWorseQualityOfTheFixesAroundIt)
{
    GnssTrack track;
    ASSERT_TRUE(track.add(0, 0, 0, 0, {3, 3, 15}));      // RTK fixed
    ASSERT_TRUE(track.add(1000, 1, 0, 1, {3, 4, 60}));   // RTK float
    ASSERT_TRUE(track.add(2000, 2, 0, 2, {2, 1, -1}));   // GPS, 2D, no estimate
    const TrackQuery first = track.position_at(500);
    EXPECT_EQ(first.quality.mode, 3);
    EXPECT_EQ(first.quality.status, 4);
    EXPECT_DOUBLE_EQ(first.quality.eph_mm, 60);
    const TrackQuery second = track.position_at(1500);
    EXPECT_EQ(second.quality.mode, 2);
    EXPECT_EQ(second.quality.status, 1);
    EXPECT_LT(second.quality.eph_mm, 0);   // unknown if either is
    // On a point: that point's own.
    EXPECT_EQ(track.position_at(0).quality.status, 3);
    EXPECT_DOUBLE_EQ(track.position_at(0).quality.eph_mm, 15);
    // Before the history: nothing known.
    EXPECT_EQ(track.position_at(-1).quality.mode, 0);
}

TEST(GnssTrack, FixesAveragedIntoOnePointKeepTheWorstQuality)
{
    GnssTrack track;
    ASSERT_TRUE(track.add(0, 0, 0, 0, {3, 3, 15}));
    ASSERT_TRUE(track.add(1, 0, 0, 1, {3, 2, 400}));   // standing: same point
    ASSERT_TRUE(track.add(2, 0, 0, 2, {3, 3, 12}));
    ASSERT_EQ(track.size(), 1u);
    EXPECT_EQ(track.newest().quality.status, 2);
    EXPECT_DOUBLE_EQ(track.newest().quality.eph_mm, 400);
}

TEST(FixQuality, StatusOrderAndNames)
{
    // RTK fixed is better than float, float than DGPS, DGPS than GPS, GPS than dead reckoning.
    EXPECT_EQ(worse({3, 3, 1}, {3, 4, 1}).status, 4);
    EXPECT_EQ(worse({3, 2, 1}, {3, 4, 1}).status, 2);
    EXPECT_EQ(worse({3, 2, 1}, {3, 1, 1}).status, 1);
    EXPECT_EQ(worse({3, 5, 1}, {3, 1, 1}).status, 5);
    EXPECT_EQ(status_name(3), "rtk_fixed");
    EXPECT_EQ(status_name(4), "rtk_float");
    EXPECT_EQ(status_name(2), "dgps");
    EXPECT_EQ(status_name(0), "none");
    EXPECT_EQ(mode_name(2), "2d");
    EXPECT_EQ(mode_name(3), "3d");
    EXPECT_EQ(mode_name(1), "none");
}
