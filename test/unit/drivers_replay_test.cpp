// The replay frame source: frames.csv with extra columns, frames copied into
// the caller's slot, corrupt and wrong-size frames counted and skipped, once/loop, pacing.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <algorithm>
#include <cstring>
#include <random>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include "forged_png.hpp"
#include "replay/replay_source.hpp"
#include "temp_dir_test.hpp"

namespace fs = std::filesystem;
using namespace stemd::drivers;
using namespace std::chrono_literals;

namespace {

const cv::Size kSize(64, 48);

std::shared_ptr<spdlog::logger> quiet_logger()
{
    return std::make_shared<spdlog::logger>("replay-test", std::make_shared<spdlog::sinks::null_sink_mt>());
}

class ReplayTest : public stemd::test::TempDirTest {
protected:
    void SetUp() override
    {
        TempDirTest::SetUp();
        fs::create_directories(dir_ / "rgb");
    }

    // Frame i is filled with the value 10 * (i + 1); t_ns = i * period_ns.
    // An odom_mm column rides along, as a recorder may write it.
    void write_recording(int frames, std::int64_t period_ns)
    {
        std::ofstream csv(dir_ / "frames.csv");
        csv << "t_ns,rgb,nir,mask,odom_mm\n";
        for (int i = 0; i < frames; ++i) {
            const std::string name = "rgb/" + std::to_string(i) + ".png";
            cv::imwrite((dir_ / name).string(), cv::Mat(kSize, CV_8UC3, cv::Scalar::all(10 * (i + 1))));
            csv << i * period_ns << "," << name << ",,," << 12.5 * i << "\n";
        }
    }

    static Frame slot()
    {
        Frame f;
        f.bgr = cv::Mat::zeros(kSize, CV_8UC3);
        return f;
    }

    ReplaySource make(ReplayOptions::Pacing pacing, bool loop, bool preload = false)
    {
        return ReplaySource({.dir = dir_, .pacing = pacing, .loop = loop, .preload = preload}, quiet_logger());
    }

    // Runs `body` on a started fast, non-looping source, once decoding each
    // frame as it comes and once preloaded: both must behave alike.
    template <typename Body>
    void each_preload(Body body)
    {
        for (const bool preload : {false, true}) {
            SCOPED_TRACE(preload ? "preload" : "decode per frame");
            auto source = make(ReplayOptions::Pacing::fast, false, preload);
            ASSERT_TRUE(source.open());
            ASSERT_TRUE(source.start());
            body(source);
        }
    }
};

}  // namespace

TEST_F(ReplayTest, DeliversEveryFrameOnceIntoTheCallersSlot)
{
    write_recording(3, 1'000'000);
    each_preload([&](ReplaySource& source) {
        EXPECT_FALSE(source.realtime());
        Frame f = slot();
        const uchar* pixels = f.bgr.data;
        for (int i = 0; i < 3; ++i) {
            ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
            EXPECT_EQ(f.bgr.data, pixels) << "the slot is never reallocated";
            EXPECT_EQ(f.bgr.at<cv::Vec3b>(5, 5)[1], 10 * (i + 1));
            EXPECT_EQ(f.t_recorded_ns, i * 1'000'000);
            EXPECT_GT(f.t_sample_ns, 0);
            EXPECT_EQ(f.t_delivered_ns, f.t_sample_ns);
            EXPECT_EQ(f.name.view(), "rgb/" + std::to_string(i) + ".png");
        }
        EXPECT_EQ(source.next(f, 1s), NextStatus::end_of_stream);
        EXPECT_EQ(source.next(f, 1s), NextStatus::end_of_stream);
        EXPECT_EQ(source.counters().delivered, 3u);
    });
}

TEST_F(ReplayTest, CorruptAndWrongSizeFramesAreCountedAndSkipped)
{
    write_recording(4, 1'000'000);
    std::ofstream(dir_ / "rgb/1.png") << "not a png";
    cv::imwrite((dir_ / "rgb/2.png").string(), cv::Mat(kSize.height + 1, kSize.width, CV_8UC3, cv::Scalar::all(1)));
    each_preload([&](ReplaySource& source) {
        Frame f = slot();
        const uchar* pixels = f.bgr.data;
        EXPECT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(source.next(f, 1s), NextStatus::skipped);
        EXPECT_EQ(source.next(f, 1s), NextStatus::skipped);
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(f.name.view(), "rgb/3.png");
        EXPECT_EQ(f.bgr.data, pixels);
        EXPECT_EQ(f.bgr.size(), kSize);
        EXPECT_EQ(source.next(f, 1s), NextStatus::end_of_stream);
        EXPECT_EQ(source.counters().corrupt, 1u);
        EXPECT_EQ(source.counters().bad_size, 1u);
        EXPECT_EQ(source.counters().delivered, 2u);
    });
}

TEST_F(ReplayTest, AJpegCutOffInItsImageDataIsCountedAsCorruptNotDeliveredHalfGrey)
{
    // libjpeg would decode it, the missing rows grey, without an error.
    write_recording(3, 1'000'000);
    cv::Mat textured(kSize, CV_8UC3);
    cv::RNG(3).fill(textured, cv::RNG::UNIFORM, 0, 256);
    std::vector<unsigned char> jpg;
    ASSERT_TRUE(cv::imencode(".jpg", textured, jpg));
    std::ofstream(dir_ / "rgb/1.png", std::ios::binary)
        .write(reinterpret_cast<const char*>(jpg.data()), static_cast<std::streamsize>(jpg.size() * 2 / 3));
    each_preload([&](ReplaySource& source) {
        Frame f = slot();
        EXPECT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(source.next(f, 1s), NextStatus::skipped);
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(f.name.view(), "rgb/2.png");
        EXPECT_EQ(source.next(f, 1s), NextStatus::end_of_stream);
        EXPECT_EQ(source.counters().corrupt, 1u);
        EXPECT_EQ(source.counters().delivered, 2u);
    });
}

TEST_F(ReplayTest, MissingFileIsCountedAsCorrupt)
{
    write_recording(2, 1'000'000);
    fs::remove(dir_ / "rgb/0.png");
    auto source = make(ReplayOptions::Pacing::fast, false);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    EXPECT_EQ(source.next(f, 1s), NextStatus::skipped);
    EXPECT_EQ(source.next(f, 1s), NextStatus::frame);
    EXPECT_EQ(source.counters().corrupt, 1u);
}

TEST_F(ReplayTest, LoopingDrivesTheStripAgainWithTheOdometerGoingOn)
{
    // Three frames 12.5 mm apart: each pass starts the recording over, and
    // its odometer goes on from one step (12.5 mm) after the last frame, as
    // the time does.
    write_recording(3, 1'000'000);
    auto source = make(ReplayOptions::Pacing::fast, true);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    for (int i = 0; i < 7; ++i) {
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(f.t_recorded_ns, (i % 3) * 1'000'000);
        EXPECT_EQ(f.odom_mm, 12.5 * i) << "frame " << i << " of the looping replay";
    }
    EXPECT_EQ(source.counters().loops, 2u);
}

TEST_F(ReplayTest, LoopingWithoutAnOdometerHasNone)
{
    std::ofstream(dir_ / "frames.csv") << "t_ns,rgb,nir,mask\n0,rgb/0.png,,\n1000,rgb/1.png,,\n";
    for (int i = 0; i < 2; ++i)
        cv::imwrite((dir_ / ("rgb/" + std::to_string(i) + ".png")).string(), cv::Mat::zeros(kSize, CV_8UC3));
    auto source = make(ReplayOptions::Pacing::fast, true);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    for (int i = 0; i < 5; ++i) {
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_TRUE(std::isnan(f.odom_mm));
    }
}

TEST_F(ReplayTest, RecordedPacingKeepsTheRecordingsIntervals)
{
    constexpr std::int64_t kPeriodNs = 40'000'000;
    write_recording(3, kPeriodNs);
    auto source = make(ReplayOptions::Pacing::recorded, false);
    EXPECT_TRUE(source.realtime());
    ASSERT_TRUE(source.open());
    // Frame i is due i periods after start(); steady_clock is CLOCK_MONOTONIC.
    const std::int64_t start_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                      std::chrono::steady_clock::now().time_since_epoch())
                                      .count();
    ASSERT_TRUE(source.start());
    Frame f = slot();
    for (int i = 0; i < 3;) {
        // A timeout shorter than the interval: next() says so rather than block.
        const NextStatus status = source.next(f, 5ms);
        if (status == NextStatus::timeout)
            continue;
        ASSERT_EQ(status, NextStatus::frame);
        // Never early; late only by scheduling (generous bound for loaded CI).
        EXPECT_GE(f.t_sample_ns - start_ns, i * kPeriodNs);
        EXPECT_LT(f.t_sample_ns - start_ns, i * kPeriodNs + 500'000'000);
        ++i;
    }
    EXPECT_EQ(source.next(f, 5ms), NextStatus::end_of_stream);
}

TEST_F(ReplayTest, BadRecordingsFailToOpen)
{
    auto no_csv = make(ReplayOptions::Pacing::fast, false);
    EXPECT_FALSE(no_csv.open());
    std::ofstream(dir_ / "frames.csv") << "time,rgb\n0,a.png\n";
    auto no_t = make(ReplayOptions::Pacing::fast, false);
    EXPECT_FALSE(no_t.open());
    std::ofstream(dir_ / "frames.csv") << "t_ns,rgb,nir,mask\nabc,a.png,,\n";
    auto bad_t = make(ReplayOptions::Pacing::fast, false);
    EXPECT_FALSE(bad_t.open());
    std::ofstream(dir_ / "frames.csv") << "t_ns,rgb,nir,mask\n";
    auto empty = make(ReplayOptions::Pacing::fast, false);
    EXPECT_FALSE(empty.open());
    Frame f = slot();
    EXPECT_EQ(empty.next(f, 1ms), NextStatus::failed);
}

namespace {

// Frames with an odom_mm column (frame 1 has none) and a class column
// (frame i's class PNG is filled with i % 3; frame 2 has none).
void write_class_recording(const fs::path& dir, int frames)
{
    fs::create_directories(dir / "class");
    std::ofstream csv(dir / "frames.csv");
    csv << "t_ns,rgb,nir,mask,class,odom_mm\n";
    for (int i = 0; i < frames; ++i) {
        const std::string rgb = "rgb/" + std::to_string(i) + ".png";
        const std::string cls = i == 2 ? "" : "class/" + std::to_string(i) + ".png";
        cv::imwrite((dir / rgb).string(), cv::Mat(kSize, CV_8UC3, cv::Scalar::all(10 * (i + 1))));
        if (!cls.empty())
            cv::imwrite((dir / cls).string(), cv::Mat(kSize, CV_8UC1, cv::Scalar(i % 3)));
        csv << 1000 * i << "," << rgb << ",,," << cls << "," << (i == 1 ? std::string() : std::to_string(46 * i))
            << "\n";
    }
}

}  // namespace

TEST_F(ReplayTest, OdometerComesFromTheRecording)
{
    write_recording(3, 1'000'000);
    each_preload([&](ReplaySource& source) {
        Frame f = slot();
        for (int i = 0; i < 3; ++i) {
            ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
            EXPECT_EQ(f.odom_mm, 12.5 * i);
            EXPECT_FALSE(f.has_class_map);
        }
    });
}

TEST_F(ReplayTest, ClassMapsFillTheClassPlaneWhenTheSlotHasOne)
{
    write_class_recording(dir_, 4);
    each_preload([&](ReplaySource& source) {
        Frame f = slot();
        f.plant_class = cv::Mat(kSize, CV_8UC1, cv::Scalar(77));
        const uchar* class_pixels = f.plant_class.data;
        for (int i = 0; i < 4; ++i) {
            ASSERT_EQ(source.next(f, 1s), NextStatus::frame) << i;
            EXPECT_EQ(f.plant_class.data, class_pixels) << "the slot is never reallocated";
            if (i == 2) {
                EXPECT_FALSE(f.has_class_map) << "a frame without a class PNG";
            } else {
                EXPECT_TRUE(f.has_class_map);
                EXPECT_EQ(f.plant_class.at<std::uint8_t>(7, 9), i % 3);
            }
            if (i == 1)
                EXPECT_TRUE(std::isnan(f.odom_mm));
            else
                EXPECT_EQ(f.odom_mm, 46.0 * i);
        }
        EXPECT_EQ(source.next(f, 1s), NextStatus::end_of_stream);
    });
}

TEST_F(ReplayTest, ClassMapsAreIgnoredWithoutAClassPlane)
{
    write_class_recording(dir_, 2);
    std::ofstream(dir_ / "class/1.png") << "corrupt, but never read";
    auto source = make(ReplayOptions::Pacing::fast, false);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    for (int i = 0; i < 2; ++i) {
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_FALSE(f.has_class_map);
        EXPECT_TRUE(f.plant_class.empty());
    }
    EXPECT_EQ(source.counters().corrupt, 0u);
}

TEST_F(ReplayTest, CorruptAndWrongSizeClassMapsSkipTheFrame)
{
    write_class_recording(dir_, 4);
    std::ofstream(dir_ / "class/1.png") << "not a png";
    cv::imwrite((dir_ / "class/3.png").string(), cv::Mat(kSize.height, kSize.width + 2, CV_8UC1, cv::Scalar(1)));
    each_preload([&](ReplaySource& source) {
        Frame f = slot();
        f.plant_class = cv::Mat::zeros(kSize, CV_8UC1);
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_TRUE(f.has_class_map);
        EXPECT_EQ(source.next(f, 1s), NextStatus::skipped);
        EXPECT_FALSE(f.has_class_map);
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(f.name.view(), "rgb/2.png");
        EXPECT_FALSE(f.has_class_map);
        EXPECT_EQ(source.next(f, 1s), NextStatus::skipped);
        EXPECT_EQ(source.next(f, 1s), NextStatus::end_of_stream);
        EXPECT_EQ(source.counters().corrupt, 1u);
        EXPECT_EQ(source.counters().bad_size, 1u);
        EXPECT_EQ(source.counters().delivered, 2u);
    });
}

TEST_F(ReplayTest, BadOdometerFailsToOpen)
{
    std::ofstream(dir_ / "frames.csv") << "t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,12\n1,b.png,,,fast\n";
    auto source = make(ReplayOptions::Pacing::fast, false);
    EXPECT_FALSE(source.open());
    std::ofstream(dir_ / "frames.csv") << "t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,nan\n";
    auto nan = make(ReplayOptions::Pacing::fast, false);
    EXPECT_FALSE(nan.open());
}

TEST_F(ReplayTest, HeadersTheToolsRejectFailToOpen)
{
    // One reader for every tool: what stemd-detect and the README refuse,
    // replay refuses too.
    for (const char* header : {"t_ns,rgb,nir,mask,speed", "t_ns,rgb", "t_ns,rgb,mask", "t_ns,nir,rgb,mask",
                               "rgb,t_ns,nir,mask", "t_ns,rgb,nir,mask,odom_mm,odom_mm", "t_ns,rgb,rgb,nir,mask"}) {
        SCOPED_TRACE(header);
        write_recording(2, 1'000'000);
        // Rows with the field count the header asks for, so only the header is at fault.
        const auto columns = std::count(header, header + std::strlen(header), ',') + 1;
        std::string rows;
        for (int i = 0; i < 2; ++i) {
            rows += std::to_string(i * 1'000'000);
            for (int c = 1; c < columns; ++c)
                rows += ",rgb/0.png";
            rows += "\n";
        }
        std::ofstream(dir_ / "frames.csv") << header << "\n" << rows;
        auto source = make(ReplayOptions::Pacing::fast, false);
        EXPECT_FALSE(source.open());
    }
}

TEST_F(ReplayTest, TimeThatWouldStallOrReorderThePacingFailsToOpen)
{
    cv::imwrite((dir_ / "rgb/a.png").string(), cv::Mat(kSize, CV_8UC3, cv::Scalar::all(1)));
    for (const char* rows : {"9223372036854775806,rgb/a.png,,\n-9223372036854775807,rgb/a.png,,\n",
                             "0,rgb/a.png,,\n1000000000000000,rgb/a.png,,\n", "-5,rgb/a.png,,\n",
                             "7,rgb/a.png,,\n7,rgb/a.png,,\n", "7,rgb/a.png,,\n6,rgb/a.png,,\n"}) {
        SCOPED_TRACE(rows);
        std::ofstream(dir_ / "frames.csv") << "t_ns,rgb,nir,mask\n" << rows;
        auto source = make(ReplayOptions::Pacing::recorded, true);
        EXPECT_FALSE(source.open());
    }
}

TEST_F(ReplayTest, AHugeDeclaredSizeIsBadSizeAndNeverDecoded)
{
    write_recording(3, 1'000'000);
    const auto png = stemd::test::png_declaring(30000, 30000);
    std::ofstream(dir_ / "rgb/1.png", std::ios::binary)
        .write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
    for (const bool preload : {false, true}) {
        SCOPED_TRACE(preload ? "preload" : "decode per frame");
        auto source = ReplaySource(
            {.dir = dir_, .pacing = ReplayOptions::Pacing::fast, .loop = false, .preload = preload, .frame_size = kSize},
            quiet_logger());
        ASSERT_TRUE(source.open());
        ASSERT_TRUE(source.start());
        Frame f = slot();
        EXPECT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(source.next(f, 1s), NextStatus::skipped);
        EXPECT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_EQ(source.counters().bad_size, 1u);
        EXPECT_EQ(source.counters().corrupt, 0u) << "refused from its header, not by a failed decode";
    }
}

TEST_F(ReplayTest, FramesTheSourceComesToLateAreCounted)
{
    write_recording(3, 1'000'000);
    auto source = make(ReplayOptions::Pacing::recorded, false);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
    // The first frame is late only if this thread was not scheduled for a
    // while (a loaded machine); what is counted from here on is the point.
    const auto late_before = source.counters().late;
    // The consumer holds on to the first frame 30 ms; the second was due
    // 1 ms after it, so it is at least 29 ms late.
    std::this_thread::sleep_for(30ms);
    ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
    EXPECT_EQ(source.counters().late, late_before + 1);
    EXPECT_GE(source.counters().worst_lateness_ms, 29.0);
}

TEST_F(ReplayTest, RecordedPacingCarriesTheNextFramesOdometerAndItsDueTime)
{
    constexpr std::int64_t kPeriodNs = 20'000'000;
    write_recording(3, kPeriodNs);   // odom_mm 0, 12.5, 25
    auto source = make(ReplayOptions::Pacing::recorded, false);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    std::int64_t t_next_before = 0;
    for (int i = 0; i < 3; ++i) {
        ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
        EXPECT_DOUBLE_EQ(f.odom_mm, 12.5 * i);
        if (i > 0) {
            // What the previous frame announced is this frame's odometer, no
            // later than this frame was handed over.
            EXPECT_LE(t_next_before, f.t_sample_ns);
        }
        // The next frame's odometer, one recorded interval after this one
        // was due (after the last: the last step again).
        EXPECT_DOUBLE_EQ(f.odom_next_mm, 12.5 * (i + 1));
        EXPECT_LE(f.t_next_ns, f.t_sample_ns + kPeriodNs);
        t_next_before = f.t_next_ns;
    }
    EXPECT_EQ(source.next(f, 1s), NextStatus::end_of_stream);
}

TEST_F(ReplayTest, FastPacingAnnouncesNoOdometerAhead)
{
    write_recording(2, 1'000'000);
    auto source = make(ReplayOptions::Pacing::fast, false);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
    EXPECT_TRUE(std::isnan(f.odom_next_mm));
}

TEST_F(ReplayTest, ALateFrameShiftsTheFramesAfterItInsteadOfABurst)
{
    constexpr std::int64_t kPeriodNs = 20'000'000;
    write_recording(3, kPeriodNs);
    auto source = make(ReplayOptions::Pacing::recorded, false);
    ASSERT_TRUE(source.open());
    ASSERT_TRUE(source.start());
    Frame f = slot();
    ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
    // The consumer keeps the first frame 100 ms: the second is 80 ms late.
    std::this_thread::sleep_for(100ms);
    const std::int64_t before_second_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                              std::chrono::steady_clock::now().time_since_epoch())
                                              .count();
    ASSERT_EQ(source.next(f, 1s), NextStatus::frame);
    EXPECT_EQ(source.counters().late, 1u);
    // The third keeps its recorded interval from the second: on the
    // recording's own clock it was due 60 ms before the second was taken.
    EXPECT_GE(f.t_next_ns, before_second_ns + kPeriodNs);
    EXPECT_DOUBLE_EQ(f.odom_next_mm, 25.0);
}
