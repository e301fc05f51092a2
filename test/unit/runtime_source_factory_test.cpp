// runtime::check_source_config and make_frame_source: the source the daemon
// and stemd-record build from the configuration.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include "runtime_test_util.hpp"
#include "stemd/config/config.hpp"
#include "stemd/runtime/daemon_config.hpp"
#include "stemd/runtime/source_factory.hpp"

namespace {

using namespace stemd;

TEST(SourceFactory, ReplayNeedsARecordingDirectory)
{
    config::Config config;
    ASSERT_FALSE(config.load_text("source:\n  kind: replay\n  replay_dir: /nonexistent/rec\n", "test.yaml"));
    const runtime::DaemonConfig d = config.settings().daemon;
    const auto problem = runtime::check_source_config(d, config, false);
    ASSERT_TRUE(problem);
    EXPECT_NE(problem->find("test.yaml:3: key 'source.replay_dir'"), std::string::npos) << *problem;
    EXPECT_NE(problem->find("not a recording directory"), std::string::npos) << *problem;

    const auto from_cli = runtime::check_source_config(d, config, true);
    ASSERT_TRUE(from_cli);
    EXPECT_EQ(from_cli->rfind("--replay: ", 0), 0u) << *from_cli;
}

TEST(SourceFactory, ReplayWithoutDirectoryIsAnErrorUnlessOnlyChecking)
{
    config::Config config;
    const runtime::DaemonConfig d = config.settings().daemon;
    ASSERT_EQ(d.source_kind, "replay");
    const auto problem = runtime::check_source_config(d, config, false);
    ASSERT_TRUE(problem);
    EXPECT_NE(problem->find("no frame source"), std::string::npos);
    EXPECT_FALSE(runtime::check_source_config(d, config, false, /*check_only=*/true));
}

TEST(SourceFactory, BuildsTheConfiguredSource)
{
    const auto dir = test::scratch_dir("source_factory");
    std::ofstream(dir / "frames.csv") << "t_ns,rgb,nir,mask\n";
    config::Config config;
    runtime::DaemonConfig d = config.settings().daemon;
    d.replay_dir = dir.string();
    EXPECT_FALSE(runtime::check_source_config(d, config, true));
    auto replay = runtime::make_frame_source(d);
    ASSERT_TRUE(replay);
    EXPECT_EQ(replay->name().rfind("replay:", 0), 0u) << replay->name();

    ASSERT_FALSE(config.set_override("source.kind=v4l2"));
    ASSERT_FALSE(config.set_override("source.v4l2_device=/dev/video7"));
    d = config.settings().daemon;
    EXPECT_FALSE(runtime::check_source_config(d, config, false));
    auto v4l2 = runtime::make_frame_source(d);
    ASSERT_TRUE(v4l2);
    EXPECT_NE(v4l2->name().find("/dev/video7"), std::string::npos) << v4l2->name();
    std::filesystem::remove_all(dir);
}

}  // namespace

namespace {

std::optional<std::string> problem_with(const std::string& yaml)
{
    config::Config config;
    if (const auto e = config.load_text(yaml, "nir.yaml"))
        return "load: " + e->to_string();
    return runtime::check_source_config(config.settings().daemon, config, false, /*check_only=*/true);
}

}  // namespace

TEST(SourceFactory, NdviFromAV4l2CameraNeedsASecondNirDevice)
{
    const auto p = problem_with("segment:\n  method: ndvi\nsource:\n  kind: v4l2\n");
    ASSERT_TRUE(p);
    EXPECT_NE(p->find("nir.yaml:2: key 'segment.method'"), std::string::npos) << *p;
    EXPECT_NE(p->find("source.nir_device"), std::string::npos) << *p;
    EXPECT_FALSE(problem_with("segment:\n  method: ndvi\nsource:\n  kind: v4l2\n  nir_device: /dev/video2\n"));
}

TEST(SourceFactory, NirDeviceMustBeAnotherV4l2DeviceWithATightTolerance)
{
    auto p = problem_with("source:\n  kind: v4l2\n  v4l2_device: /dev/video0\n  nir_device: /dev/video0\n");
    ASSERT_TRUE(p);
    EXPECT_NE(p->find("nir.yaml:4: key 'source.nir_device'"), std::string::npos) << *p;

    // 30 fps: half the period is 16.7 ms.
    p = problem_with("source:\n  kind: v4l2\n  nir_device: /dev/video2\n  nir_tolerance_ms: 20\n");
    ASSERT_TRUE(p);
    EXPECT_NE(p->find("nir.yaml:4: key 'source.nir_tolerance_ms'"), std::string::npos) << *p;
    EXPECT_FALSE(problem_with("source:\n  kind: v4l2\n  nir_device: /dev/video2\n  nir_tolerance_ms: 16\n"));

    p = problem_with("source:\n  kind: replay\n  nir_device: /dev/video2\n");
    ASSERT_TRUE(p);
    EXPECT_NE(p->find("key 'source.nir_device'"), std::string::npos) << *p;
}

TEST(SourceFactory, ANirDeviceBuildsThePairedSource)
{
    config::Config config;
    ASSERT_FALSE(config.load_text("source:\n  kind: v4l2\n  v4l2_device: /dev/video7\n  nir_device: /dev/video8\n",
                                  "nir.yaml"));
    const auto source = runtime::make_frame_source(config.settings().daemon);
    ASSERT_TRUE(source);
    EXPECT_NE(source->name().find("/dev/video7"), std::string::npos) << source->name();
    EXPECT_NE(source->name().find("/dev/video8"), std::string::npos) << source->name();
}

// segment.method auto takes NIR where every frame brings it, and names why.
TEST(SourceFactory, AutoSegmentationFollowsTheSourcesNirPlane)
{
    using vision::Segmentation;
    const auto dir = test::scratch_dir("source_factory_auto");
    std::filesystem::create_directories(dir / "with_nir");
    std::filesystem::create_directories(dir / "one_without");
    std::ofstream(dir / "with_nir" / "frames.csv") << "t_ns,rgb,nir,mask\n0,a.png,a_nir.png,\n100,b.png,b_nir.png,\n";
    std::ofstream(dir / "one_without" / "frames.csv") << "t_ns,rgb,nir,mask\n0,a.png,a_nir.png,\n100,b.png,,\n";
    const auto resolved = [](const std::string& yaml, std::string* line = nullptr) {
        config::Config config;
        EXPECT_FALSE(config.load_text(yaml, "auto.yaml"));
        runtime::DaemonConfig d = config.settings().daemon;
        EXPECT_EQ(d.vision.segmentation, Segmentation::automatic);   // the default
        const std::string choice = runtime::resolve_auto_segmentation(d);
        if (line)
            *line = choice;
        return d.vision.segmentation;
    };
    std::string line;
    EXPECT_EQ(resolved("source:\n  kind: replay\n  replay_dir: " + (dir / "with_nir").string() + "\n", &line),
              Segmentation::exg_and_ndvi);
    EXPECT_EQ(line, "segment.method auto: exg_and_ndvi (every replayed frame has a nir image)");
    EXPECT_EQ(resolved("source:\n  kind: replay\n  replay_dir: " + (dir / "one_without").string() + "\n"),
              Segmentation::chromatic_exg);
    EXPECT_EQ(resolved("source:\n  kind: replay\n  replay_dir: " + (dir / "absent").string() + "\n"),
              Segmentation::chromatic_exg);
    EXPECT_EQ(resolved("source:\n  kind: v4l2\n  nir_device: /dev/video2\n", &line), Segmentation::exg_and_ndvi);
    EXPECT_NE(line.find("source.nir_device /dev/video2"), std::string::npos) << line;
    EXPECT_EQ(resolved("source:\n  kind: v4l2\n"), Segmentation::chromatic_exg);
    EXPECT_EQ(resolved("source:\n  kind: libcamera\n", &line), Segmentation::chromatic_exg);
    EXPECT_NE(line.find("libcamera"), std::string::npos) << line;

    // A method set by hand stays, and there is nothing to log.
    config::Config config;
    ASSERT_FALSE(config.load_text("segment:\n  method: ndvi\nsource:\n  kind: replay\n  replay_dir: " +
                                      (dir / "one_without").string() + "\n",
                                  "auto.yaml"));
    runtime::DaemonConfig d = config.settings().daemon;
    EXPECT_EQ(runtime::resolve_auto_segmentation(d), "");
    EXPECT_EQ(d.vision.segmentation, Segmentation::ndvi);
}

TEST(SourceFactory, AutoOdometryIsTheRecordingsColumnWhenAnyReplayedFrameCarriesIt)
{
    using runtime::OdometrySource;
    const auto dir = test::scratch_dir("source_factory_auto_odometry");
    std::filesystem::create_directories(dir / "some_odom");
    std::filesystem::create_directories(dir / "no_odom");
    // What stemd-record leaves where the odometer was not known: an empty cell.
    std::ofstream(dir / "some_odom" / "frames.csv") << "t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,\n100,b.png,,,46.5\n";
    std::ofstream(dir / "no_odom" / "frames.csv") << "t_ns,rgb,nir,mask\n0,a.png,,\n100,b.png,,\n";
    const auto resolved = [](const std::string& yaml, std::string* line = nullptr) {
        config::Config config;
        EXPECT_FALSE(config.load_text(yaml, "auto.yaml"));
        runtime::ActuationConfig a = config.settings().actuation;
        EXPECT_EQ(a.odometry, OdometrySource::automatic);   // the default
        const std::string choice = runtime::resolve_auto_odometry(config.settings().daemon, a);
        if (line)
            *line = choice;
        return a.odometry;
    };
    std::string line;
    EXPECT_EQ(resolved("source:\n  kind: replay\n  replay_dir: " + (dir / "some_odom").string() + "\n", &line),
              OdometrySource::recording);
    EXPECT_EQ(line, "odometry.source auto: recording (1 of 2 replayed frames carry odom_mm; the others are not "
                    "actuated)");
    EXPECT_EQ(resolved("source:\n  kind: replay\n  replay_dir: " + (dir / "no_odom").string() + "\n", &line),
              OdometrySource::constant);
    EXPECT_NE(line.find("carry no odom_mm"), std::string::npos) << line;
    EXPECT_EQ(resolved("source:\n  kind: v4l2\n", &line), OdometrySource::constant);
    EXPECT_NE(line.find("a camera has no odometer"), std::string::npos) << line;

    // A source set by hand stays, and there is nothing to log.
    config::Config config;
    ASSERT_FALSE(config.load_text("odometry:\n  source: constant\nsource:\n  kind: replay\n  replay_dir: " +
                                      (dir / "some_odom").string() + "\n",
                                  "auto.yaml"));
    runtime::ActuationConfig a = config.settings().actuation;
    EXPECT_EQ(runtime::resolve_auto_odometry(config.settings().daemon, a), "");
    EXPECT_EQ(a.odometry, OdometrySource::constant);
}
