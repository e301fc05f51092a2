// GnssInput: fixes onto the odometer-keyed track (receive time or the fix's
// own time), plants placed from their field coordinates with the antenna
// offset and the track's heading, and the georef statuses; the plant map's
// georef keys and the GeoJSON made from the map.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "stemd/runtime/gnss_input.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/runtime/plant_geojson.hpp"
#include "stemd/runtime/plant_map.hpp"

using namespace stemd;
using namespace stemd::runtime;

namespace {

constexpr std::int64_t kT0 = 1'000'000'000;     // the odometer starts (0 mm) here
constexpr std::int64_t kMs = 1'000'000;
constexpr double kSpeed = 1000;                  // mm/s
constexpr double kPi = 3.14159265358979323846;
const geometry::Geodetic kOrigin{50.6255, 6.9912, 180};
const double kHeading = kPi / 4;                 // north-east

ActuationConfig constant_odometry()
{
    ActuationConfig c;
    c.odometry = OdometrySource::constant;
    c.speed_mm_per_s = kSpeed;
    return c;
}

GnssConfig gnss_config()
{
    GnssConfig g;
    g.source = GnssSourceKind::gpsd;
    g.antenna_x_mm = -500;
    g.antenna_y_mm = 100;
    g.heading_baseline_mm = 1000;
    g.max_extrapolation_mm = 300;
    g.max_age_ns = 1000 * kMs;
    return g;
}

// The antenna at odometer odom_mm: along kHeading from kOrigin.
drivers::GnssFix fix_at(std::int64_t t_ns, double odom_mm)
{
    const geometry::LocalTangentPlane ltp(kOrigin);
    const geometry::Geodetic g = ltp.to_geodetic(
        {odom_mm * 1e-3 * std::cos(kHeading), odom_mm * 1e-3 * std::sin(kHeading), 0});
    drivers::GnssFix f;
    f.timestamp_sample_ns = t_ns;
    f.mode = 3;
    f.lat_deg = g.lat_deg;
    f.lon_deg = g.lon_deg;
    f.height_m = g.height_m;
    return f;
}

// Distance (m) in the plane from a placed plant to the machine point (x, y)
// at odometer s_mm.
double error_m(const GeorefResult& r, double s_mm, double x_mm, double y_mm)
{
    const geometry::LocalTangentPlane ltp(kOrigin);
    const geometry::Enu p = ltp.to_enu({r.lat_deg, r.lon_deg, kOrigin.height_m});
    // Machine origin at odometer s: the antenna (at s along the track) minus
    // the antenna's offset, rotated.
    const geometry::PlaneOffset to_point = geometry::machine_to_enu(x_mm - (-500), y_mm - 100, kHeading);
    const double e = s_mm * 1e-3 * std::cos(kHeading) + to_point.e_m;
    const double n = s_mm * 1e-3 * std::sin(kHeading) + to_point.n_m;
    return std::hypot(p.e_m - e, p.n_m - n);
}

struct Fixture {
    ActuationConfig config = constant_odometry();
    ActuationCounters counters;
    OdometryInput odometry{config, counters};
    Fixture() { odometry.add_frame(kT0, std::numeric_limits<double>::quiet_NaN()); }
};

}  // namespace

TEST(GnssInput, WithoutAFixEveryPlantIsNoFix)
{
    GnssInput in(gnss_config(), 300);
    const GeorefResult r = in.place(1000, 0, kT0);
    EXPECT_EQ(r.status, GeorefStatus::no_fix);
    EXPECT_EQ(to_string(r.status), "no_fix");
}

TEST(GnssInput, PlacesAPlantFromTheFixesAroundItsOdometerReading)
{
    Fixture f;
    GnssInput in(gnss_config(), 300);
    // 10 Hz fixes over 4 m: each at the odometer of its receive time.
    for (int k = 0; k <= 40; ++k) {
        const std::int64_t t = kT0 + k * 100 * kMs;
        in.add(fix_at(t, kSpeed * (t - kT0) * 1e-9), f.odometry, t, 0);
    }
    EXPECT_EQ(in.counters().on_track, 41u);
    const std::int64_t now = kT0 + 4000 * kMs;
    for (const double s : {1234.5, 2000.0, 3999.0}) {
        const GeorefResult r = in.place(s, -150, now);
        ASSERT_EQ(r.status, GeorefStatus::fix) << s;
        // The plant is at machine (principal x = 300, y = -150) when the odometer reads s.
        EXPECT_LT(error_m(r, s, 300, -150), 1e-6) << s;
    }
    // Past the newest fix: along the heading up to max_extrapolation_mm, then no fix.
    const GeorefResult ahead = in.place(4200, -150, now);
    ASSERT_EQ(ahead.status, GeorefStatus::extrapolated);
    EXPECT_LT(error_m(ahead, 4200, 300, -150), 1e-6);
    EXPECT_EQ(in.place(4400, -150, now).status, GeorefStatus::no_fix);
    // The same, once the newest fix is older than max_age: stale.
    EXPECT_EQ(in.place(4200, -150, now + 1500 * kMs).status, GeorefStatus::stale);
    EXPECT_EQ(in.place(4400, -150, now + 1500 * kMs).status, GeorefStatus::stale);
    // Before the first fix kept.
    EXPECT_EQ(in.place(-10, 0, now).status, GeorefStatus::no_fix);
}

TEST(GnssInput, TooLittleTravelGivesNoHeading)
{
    Fixture f;
    GnssInput in(gnss_config(), 300);
    for (int k = 0; k <= 5; ++k) {   // 500 mm: less than the 1000 mm baseline
        const std::int64_t t = kT0 + k * 100 * kMs;
        in.add(fix_at(t, kSpeed * (t - kT0) * 1e-9), f.odometry, t, 0);
    }
    EXPECT_EQ(in.place(250, 0, kT0 + 500 * kMs).status, GeorefStatus::no_heading);
}

TEST(GnssInput, TheFixOwnTimeFindsItsOdometerReading)
{
    Fixture f;
    GnssConfig g = gnss_config();
    g.time = GnssTime::gnss;
    GnssInput in(g, 300);
    // Received 150 ms late (a slow serial link): with gnss.time gnss that
    // does not matter; the UTC time is the monotonic time plus the offset.
    const std::int64_t offset = 1'700'000'000'000'000'000;
    for (int k = 0; k <= 30; ++k) {
        const std::int64_t t = kT0 + k * 100 * kMs;
        drivers::GnssFix fix = fix_at(t + 150 * kMs, kSpeed * (t - kT0) * 1e-9);
        fix.gnss_time_ns = t + offset;
        in.add(fix, f.odometry, t + 150 * kMs, offset);
    }
    const GeorefResult r = in.place(1500, 80, kT0 + 3000 * kMs);
    ASSERT_EQ(r.status, GeorefStatus::fix);
    EXPECT_LT(error_m(r, 1500, 300, 80), 1e-6);
    // A fix without its own time cannot be placed by it.
    drivers::GnssFix no_time = fix_at(kT0, 0);
    in.add(no_time, f.odometry, kT0, offset);
    EXPECT_EQ(in.counters().unplaced, 1u);
}

TEST(GnssInput, ReceiveTimeLatencyShowsAsAnAlongTrackError)
{
    // The same late fixes by their receive time: 150 ms at 1 m/s puts the
    // plant 150 mm off (why gnss.time gnss exists).
    Fixture f;
    GnssInput in(gnss_config(), 300);
    for (int k = 0; k <= 30; ++k) {
        const std::int64_t t = kT0 + k * 100 * kMs;
        in.add(fix_at(t + 150 * kMs, kSpeed * (t - kT0) * 1e-9), f.odometry, t + 150 * kMs, 0);
    }
    const GeorefResult r = in.place(1500, 80, kT0 + 3200 * kMs);
    ASSERT_EQ(r.status, GeorefStatus::fix);
    EXPECT_NEAR(error_m(r, 1500, 300, 80), 0.150, 1e-6);
}

TEST(GnssInput, AFixAheadOfTheOdometerWaitsForIt)
{
    ActuationConfig config;
    config.odometry = OdometrySource::recording;
    config.max_extrapolation_ns = 1000 * kMs;
    ActuationCounters counters;
    OdometryInput odometry(config, counters);
    odometry.add_frame(kT0, 0);
    GnssInput in(gnss_config(), 0);
    // Received after the newest odometer sample: not placed by extrapolation.
    in.add(fix_at(kT0 + 50 * kMs, 50), odometry, kT0 + 50 * kMs, 0);
    EXPECT_EQ(in.counters().on_track, 0u);
    EXPECT_EQ(in.counters().unplaced, 0u);
    // The next frame's odometer covers it.
    odometry.add_frame(kT0 + 100 * kMs, 100);
    struct NoFixes final : drivers::GnssSource {
        std::string_view name() const override { return "none"; }
        bool start() override { return true; }
        void stop() override {}
        bool try_pop(drivers::GnssFix&) noexcept override { return false; }
        drivers::GnssCounters counters() const override { return {}; }
    } source;
    in.poll(source, odometry, kT0 + 100 * kMs, 0);
    EXPECT_EQ(in.counters().on_track, 1u);
    EXPECT_NEAR(in.track().newest().odom_mm, 50, 1e-9);
    // One that waits past max_age is dropped, counted.
    in.add(fix_at(kT0 + 200 * kMs, 200), odometry, kT0 + 200 * kMs, 0);
    in.poll(source, odometry, kT0 + 1300 * kMs, 0);
    EXPECT_EQ(in.counters().unplaced, 1u);
}

namespace {

drivers::GnssFix with_quality(drivers::GnssFix f, std::uint8_t mode, std::uint8_t status, double eph_m)
{
    f.mode = mode;
    f.quality = status;
    f.eph_m = eph_m;
    return f;
}

}  // namespace

TEST(GnssInput, AnErrorEstimateAboveMaxEphMarksThePlantDegradedButPlacesIt)
{
    Fixture f;
    GnssConfig config = gnss_config();
    config.max_eph_mm = 50;
    GnssInput in(config, 300);
    // 10 Hz over 4 m: RTK fixed (eph 20 mm) up to 2 m, then DGPS (eph
    // 800 mm) from 2.1 m on.
    for (int k = 0; k <= 40; ++k) {
        const std::int64_t t = kT0 + k * 100 * kMs;
        const double odom = kSpeed * (t - kT0) * 1e-9;
        const drivers::GnssFix fix = k <= 20 ? with_quality(fix_at(t, odom), 3, 3, 0.020)
                                             : with_quality(fix_at(t, odom), 2, 2, 0.800);
        in.add(fix, f.odometry, t, 0);
    }
    const std::int64_t now = kT0 + 4000 * kMs;
    const GeorefResult good = in.place(1500, 0, now);
    ASSERT_EQ(good.status, GeorefStatus::fix);
    EXPECT_EQ(good.quality.mode, 3);
    EXPECT_EQ(good.quality.status, 3);
    EXPECT_DOUBLE_EQ(good.quality.eph_mm, 20);
    // Between the last RTK fix (2.0 m) and the first DGPS one (2.1 m): the worse of the two.
    const GeorefResult edge = in.place(2050, 0, now);
    ASSERT_EQ(edge.status, GeorefStatus::degraded);
    EXPECT_EQ(edge.quality.mode, 2);
    EXPECT_EQ(edge.quality.status, 2);
    EXPECT_DOUBLE_EQ(edge.quality.eph_mm, 800);
    // Degraded still has its position (same as a trusted one would).
    const GeorefResult bad = in.place(3000, -150, now);
    ASSERT_EQ(bad.status, GeorefStatus::degraded);
    EXPECT_TRUE(has_position(bad.status));
    EXPECT_LT(error_m(bad, 3000, 300, -150), 1e-6);
    // Past the newest fix: the newest fix's quality decides.
    EXPECT_EQ(in.place(4200, 0, now).status, GeorefStatus::degraded);
    EXPECT_EQ(in.counters().degraded, 3u);
    // The status line's view: the newest fix taken.
    EXPECT_EQ(in.counters().last.mode, 2);
    EXPECT_EQ(in.counters().last.status, 2);
    EXPECT_DOUBLE_EQ(in.counters().last.eph_mm, 800);
}

TEST(GnssInput, AnUnknownErrorEstimateIsNotDegradedAndStaysUnknown)
{
    Fixture f;
    GnssConfig config = gnss_config();
    config.max_eph_mm = 1;
    GnssInput in(config, 300);
    for (int k = 0; k <= 20; ++k) {
        const std::int64_t t = kT0 + k * 100 * kMs;
        in.add(with_quality(fix_at(t, kSpeed * (t - kT0) * 1e-9), 3, 1, -1), f.odometry, t, 0);
    }
    const GeorefResult r = in.place(1000, 0, kT0 + 2000 * kMs);
    EXPECT_EQ(r.status, GeorefStatus::fix);
    EXPECT_LT(r.quality.eph_mm, 0);
    EXPECT_EQ(in.counters().degraded, 0u);
}

namespace {

std::filesystem::path temp_dir()
{
    const auto dir = std::filesystem::temp_directory_path() / ("stemd-gnss-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    return dir;
}

std::vector<std::string> lines_of(const std::filesystem::path& p)
{
    std::ifstream in(p);
    std::vector<std::string> out;
    for (std::string line; std::getline(in, line);)
        out.push_back(line);
    return out;
}

}  // namespace

TEST(PlantMapGeoref, KeysAreAppendedOnlyWithGnss)
{
    const auto dir = temp_dir();
    PlantMap map(make_logger("map"));
    ASSERT_TRUE(map.open(dir / "map.jsonl"));
    actuation::RetiredTrack t;
    t.s_mm = 1200;
    t.y_mm = -40;
    MapEntry off;
    off.reason = MapReason::policy;
    MapEntry placed = off;
    placed.georef = {GeorefStatus::fix, 50.625512345, 6.991298765, {3, 3, 14.5}};
    MapEntry lost = off;
    lost.georef.status = GeorefStatus::stale;
    ASSERT_TRUE(map.write(t, off));
    ASSERT_TRUE(map.write(t, placed));
    ASSERT_TRUE(map.write(t, lost));
    ASSERT_TRUE(map.close());
    const auto lines = lines_of(dir / "map.jsonl");
    ASSERT_EQ(lines.size(), 3u);
    const auto a = nlohmann::json::parse(lines[0]);
    EXPECT_FALSE(a.contains("georef"));
    EXPECT_FALSE(a.contains("lat_deg"));
    const auto b = nlohmann::json::parse(lines[1]);
    EXPECT_EQ(b["georef"], "fix");
    EXPECT_NEAR(b["lat_deg"].get<double>(), 50.625512345, 1e-9);
    EXPECT_NEAR(b["lon_deg"].get<double>(), 6.991298765, 1e-9);
    // Appended after the existing keys: the line ends with them.
    EXPECT_NE(lines[1].find("\"reason\":\"policy\",\"lat_deg\""), std::string::npos) << lines[1];
    EXPECT_EQ(b["gnss_mode"], "3d");
    EXPECT_EQ(b["gnss_status"], "rtk_fixed");
    EXPECT_DOUBLE_EQ(b["eph_mm"].get<double>(), 14.5);
    const auto c = nlohmann::json::parse(lines[2]);
    EXPECT_EQ(c["georef"], "stale");
    EXPECT_TRUE(c["lat_deg"].is_null());
    EXPECT_TRUE(c["lon_deg"].is_null());
    // No fix behind it: no mode, no status, no estimate.
    EXPECT_EQ(c["gnss_mode"], "none");
    EXPECT_EQ(c["gnss_status"], "none");
    EXPECT_TRUE(c["eph_mm"].is_null());
    EXPECT_EQ(c["s_mm"].get<double>(), 1200);
    std::filesystem::remove_all(dir);
}

TEST(PlantGeojson, PointsInLonLatOrderNullWithoutAPositionAndIncremental)
{
    const auto dir = temp_dir();
    const auto map_path = dir / "map.jsonl";
    {
        std::ofstream m(map_path);
        m << R"({"id":3,"s_mm":100.0,"y_mm":-5.0,"class":"weed","leaves":4,"sightings":5,"first_frame":1,)"
             R"("last_frame":5,"treated":true,"reason":"sent","tool":0,"lane":0,"fire_odom_mm":700.0,)"
             R"("lat_deg":50.625500001,"lon_deg":6.991200002,"georef":"fix"})" "\n";
        m << R"({"id":4,"s_mm":200.0,"y_mm":7.5,"class":"crop","leaves":6,"sightings":5,"first_frame":2,)"
             R"("last_frame":6,"treated":false,"reason":"policy","lat_deg":null,"lon_deg":null,"georef":"no_fix"})"
             "\n";
        m << R"({"id":5,"s_mm":300.0)";   // a line still being written
    }
    PlantGeojson g(map_path);
    std::string error;
    ASSERT_TRUE(g.update(error)) << error;
    ASSERT_TRUE(g.write(dir / "map.geojson", error)) << error;
    EXPECT_FALSE(std::filesystem::exists(dir / "map.geojson.tmp"));
    std::ifstream in(dir / "map.geojson");
    const auto doc = nlohmann::json::parse(in);
    EXPECT_EQ(doc["type"], "FeatureCollection");
    ASSERT_EQ(doc["features"].size(), 2u);
    const auto& f0 = doc["features"][0];
    EXPECT_EQ(f0["type"], "Feature");
    EXPECT_EQ(f0["geometry"]["type"], "Point");
    EXPECT_DOUBLE_EQ(f0["geometry"]["coordinates"][0].get<double>(), 6.991200002);   // longitude first
    EXPECT_DOUBLE_EQ(f0["geometry"]["coordinates"][1].get<double>(), 50.625500001);
    EXPECT_EQ(f0["properties"]["class"], "weed");
    EXPECT_EQ(f0["properties"]["treated"], true);
    EXPECT_EQ(f0["properties"]["reason"], "sent");
    EXPECT_EQ(f0["properties"]["leaves"], 4);
    EXPECT_EQ(f0["properties"]["s_mm"], 100.0);
    EXPECT_EQ(f0["properties"]["y_mm"], -5.0);
    EXPECT_TRUE(doc["features"][1]["geometry"].is_null());
    EXPECT_EQ(doc["features"][1]["properties"]["georef"], "no_fix");
    EXPECT_EQ(g.placed(), 1u);

    // The rest of the line arrives, and one more: read from where it stopped.
    {
        std::ofstream m(map_path, std::ios::app);
        m << R"(,"y_mm":0.0,"class":"weed","leaves":2,"treated":true,"reason":"sent"})" "\n";
    }
    ASSERT_TRUE(g.update(error)) << error;
    EXPECT_EQ(g.features(), 3u);
    {
        std::ofstream m(map_path, std::ios::app);
        m << "not json\n";
    }
    EXPECT_FALSE(g.update(error));
    EXPECT_NE(error.find(":4: not a plant map line"), std::string::npos) << error;
    std::filesystem::remove_all(dir);
}

TEST(PlantMapGeoref, DegradedKeepsItsPositionAndTheFixQuality)
{
    const auto dir = temp_dir();
    PlantMap map(make_logger("map"));
    ASSERT_TRUE(map.open(dir / "map.jsonl"));
    actuation::RetiredTrack t;
    MapEntry e;
    e.reason = MapReason::policy;
    e.georef = {GeorefStatus::degraded, 50.625512345, 6.991298765, {2, 4, 1234.5}};
    ASSERT_TRUE(map.write(t, e));
    ASSERT_TRUE(map.close());
    const auto lines = lines_of(dir / "map.jsonl");
    ASSERT_EQ(lines.size(), 1u);
    const auto j = nlohmann::json::parse(lines[0]);
    EXPECT_EQ(j["georef"], "degraded");
    EXPECT_NEAR(j["lat_deg"].get<double>(), 50.625512345, 1e-9);
    EXPECT_EQ(j["gnss_mode"], "2d");
    EXPECT_EQ(j["gnss_status"], "rtk_float");
    EXPECT_DOUBLE_EQ(j["eph_mm"].get<double>(), 1234.5);
    // The GeoJSON keeps the point and says why it is not to be trusted.
    PlantGeojson g(dir / "map.jsonl");
    std::string error;
    ASSERT_TRUE(g.update(error)) << error;
    ASSERT_TRUE(g.write(dir / "map.geojson", error)) << error;
    std::ifstream in(dir / "map.geojson");
    const auto doc = nlohmann::json::parse(in);
    ASSERT_EQ(doc["features"].size(), 1u);
    EXPECT_EQ(doc["features"][0]["geometry"]["type"], "Point");
    EXPECT_EQ(doc["features"][0]["properties"]["georef"], "degraded");
    EXPECT_EQ(doc["features"][0]["properties"]["gnss_status"], "rtk_float");
    EXPECT_DOUBLE_EQ(doc["features"][0]["properties"]["eph_mm"].get<double>(), 1234.5);
    std::filesystem::remove_all(dir);
}
