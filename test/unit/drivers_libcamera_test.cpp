// The libcamera source without a camera: copying a plane into a preallocated
// slot (both byte orders, row padding), camera selection by index, id or
// part of the id, capture times, and a clear error when no camera matches.
// Built only when libcamera was found (STEMD_HAVE_LIBCAMERA).
#include <gtest/gtest.h>

#if STEMD_HAVE_LIBCAMERA

#include <chrono>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include "libcamera/libcamera_source.hpp"
#include "captured_log.hpp"
#include "frame_source_test_util.hpp"

using namespace stemd::drivers;
using namespace std::chrono_literals;

namespace {

using stemd::test::CapturedLog;

// A packed plane of `size` with rows `stride` apart (padding 0xEE), pixel
// (x, y) = bytes (x, y, x + y) in memory.
std::vector<std::uint8_t> plane_of(cv::Size size, std::size_t stride)
{
    std::vector<std::uint8_t> out(stride * static_cast<std::size_t>(size.height), 0xEE);
    for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
            std::uint8_t* p = out.data() + static_cast<std::size_t>(y) * stride + 3 * static_cast<std::size_t>(x);
            p[0] = static_cast<std::uint8_t>(x), p[1] = static_cast<std::uint8_t>(y),
            p[2] = static_cast<std::uint8_t>(x + y);
        }
    return out;
}

}  // namespace

TEST(LibcameraPlane, Rgb888IsCopiedAsBgrIntoTheSlotsOwnBuffer)
{
    const cv::Size size(40, 30);
    const std::size_t stride = 40 * 3 + 8;  // row padding
    const auto bytes = plane_of(size, stride);
    cv::Mat slot(size, CV_8UC3, cv::Scalar::all(0));
    const std::uint8_t* before = slot.data;
    ASSERT_EQ(copy_plane_to_bgr(bytes.data(), bytes.size(), stride, size, LibcameraByteOrder::bgr, slot),
              PlaneStatus::ok);
    EXPECT_EQ(slot.data, before);
    EXPECT_EQ(slot.at<cv::Vec3b>(7, 11), cv::Vec3b(11, 7, 18));   // memory order B, G, R = OpenCV's
    EXPECT_EQ(slot.at<cv::Vec3b>(29, 39), cv::Vec3b(39, 29, 68));
}

TEST(LibcameraPlane, Bgr888IsSwappedIntoBgr)
{
    const cv::Size size(16, 8);
    const auto bytes = plane_of(size, 48);
    cv::Mat slot(size, CV_8UC3, cv::Scalar::all(0));
    const std::uint8_t* before = slot.data;
    ASSERT_EQ(copy_plane_to_bgr(bytes.data(), bytes.size(), 48, size, LibcameraByteOrder::rgb, slot),
              PlaneStatus::ok);
    EXPECT_EQ(slot.data, before);
    EXPECT_EQ(slot.at<cv::Vec3b>(5, 3), cv::Vec3b(8, 5, 3));
}

TEST(LibcameraPlane, WrongSlotOrShortPlaneIsReportedNotWritten)
{
    const cv::Size size(16, 8);
    const auto bytes = plane_of(size, 48);
    cv::Mat small(cv::Size(8, 8), CV_8UC3, cv::Scalar::all(1));
    EXPECT_EQ(copy_plane_to_bgr(bytes.data(), bytes.size(), 48, size, LibcameraByteOrder::bgr, small),
              PlaneStatus::bad_size);
    EXPECT_EQ(small.size(), cv::Size(8, 8));
    cv::Mat grey(size, CV_8UC1, cv::Scalar::all(1));
    EXPECT_EQ(copy_plane_to_bgr(bytes.data(), bytes.size(), 48, size, LibcameraByteOrder::bgr, grey),
              PlaneStatus::bad_size);
    cv::Mat slot(size, CV_8UC3, cv::Scalar::all(1));
    EXPECT_EQ(copy_plane_to_bgr(bytes.data(), bytes.size(), 40, size, LibcameraByteOrder::bgr, slot),
              PlaneStatus::bad_size);  // stride shorter than a row
    EXPECT_EQ(copy_plane_to_bgr(bytes.data(), 48 * 7 + 47, 48, size, LibcameraByteOrder::bgr, slot),
              PlaneStatus::corrupt);
    EXPECT_EQ(copy_plane_to_bgr(bytes.data(), 48 * 7 + 48, 48, size, LibcameraByteOrder::bgr, slot),
              PlaneStatus::ok);  // the last row needs no padding
    EXPECT_EQ(copy_plane_to_bgr(nullptr, 0, 48, size, LibcameraByteOrder::bgr, slot), PlaneStatus::corrupt);
}

TEST(LibcameraSelect, ByIndexIdOrUniquePartOfTheId)
{
    const std::vector<std::string> ids{"platform/vimc.0 Sensor B", "\\_SB_.PCI0.XHC_.RHUB.HS01-1:1.0-046d:0825"};
    std::string why;
    EXPECT_EQ(select_camera(ids, "0", why), 0u);
    EXPECT_EQ(select_camera(ids, "1", why), 1u);
    EXPECT_EQ(select_camera(ids, "platform/vimc.0 Sensor B", why), 0u);
    EXPECT_EQ(select_camera(ids, "vimc", why), 0u);
    EXPECT_EQ(select_camera(ids, "046d:0825", why), 1u);

    EXPECT_FALSE(select_camera(ids, "2", why));
    EXPECT_NE(why.find("no camera with index 2 (cameras: [0] 'platform/vimc.0 Sensor B', [1] '"), std::string::npos)
        << why;
    EXPECT_FALSE(select_camera(ids, "imx219", why));
    EXPECT_NE(why.find("no camera matches 'imx219'"), std::string::npos) << why;
    EXPECT_FALSE(select_camera(ids, ".", why));
    EXPECT_NE(why.find("'.' matches several cameras"), std::string::npos) << why;
    EXPECT_FALSE(select_camera({}, "0", why));
    EXPECT_NE(why.find("(cameras: none)"), std::string::npos) << why;
}

TEST(LibcameraTime, SensorTimestampCappedAtDequeueElseDequeueTime)
{
    EXPECT_EQ(libcamera_capture_time_ns(std::int64_t{1'000}, 5'000), 1'000);
    EXPECT_EQ(libcamera_capture_time_ns(std::int64_t{9'000}, 5'000), 5'000);
    EXPECT_EQ(libcamera_capture_time_ns(std::nullopt, 5'000), 5'000);
    EXPECT_EQ(libcamera_capture_time_ns(std::int64_t{0}, 5'000), 5'000);
}

// When a streaming camera counts as lost (fake time; 0 turns a limit off).
TEST(LibcameraWatchdog, FirstFrameThenStallTimeouts)
{
    constexpr std::int64_t ms = 1'000'000;
    StreamWatchdog w(5000 * ms, 2000 * ms, 8);
    w.started(1000 * ms);
    EXPECT_EQ(w.check(1000 * ms), StreamLoss::none);
    EXPECT_EQ(w.limit_ns(), 5000 * ms);
    EXPECT_EQ(w.check(6000 * ms - 1), StreamLoss::none);
    EXPECT_EQ(w.check(6000 * ms), StreamLoss::no_first_frame);  // exactly at the limit
    w.frame(5500 * ms);
    EXPECT_EQ(w.limit_ns(), 2000 * ms);
    EXPECT_EQ(w.check(7500 * ms - 1), StreamLoss::none);
    EXPECT_EQ(w.check(7500 * ms), StreamLoss::stalled);
    w.frame(7400 * ms);
    EXPECT_EQ(w.check(7500 * ms), StreamLoss::none);
    w.started(10'000 * ms);  // a restart waits for a first frame again
    EXPECT_EQ(w.check(14'000 * ms), StreamLoss::none);
    EXPECT_EQ(w.check(15'000 * ms), StreamLoss::no_first_frame);
}

TEST(LibcameraWatchdog, FailedRequestsInARow)
{
    StreamWatchdog w(0, 0, 3);  // no time limits
    w.started(0);
    w.failed_request();
    w.failed_request();
    EXPECT_EQ(w.check(1'000'000'000'000), StreamLoss::none);
    w.frame(5);  // a good frame breaks the row
    EXPECT_EQ(w.failed_in_row(), 0u);
    for (int i = 0; i < 3; ++i)
        w.failed_request();
    EXPECT_EQ(w.check(6), StreamLoss::failed_requests);
    EXPECT_NE(to_string(StreamLoss::failed_requests), "?");

    StreamWatchdog off(0, 0, 0);
    off.started(0);
    for (int i = 0; i < 100; ++i)
        off.failed_request();
    EXPECT_EQ(off.check(1'000'000'000'000), StreamLoss::none);
}

TEST(LibcameraSource, ReopenDefaultsAreAReopenBackoff)
{
    const LibcameraOptions o;
    const ReopenBackoff b(o.reopen_min, o.reopen_max);
    EXPECT_EQ(b.current_delay_ns(), 100'000'000);
    EXPECT_EQ(b.max_ns(), 5'000'000'000);
    EXPECT_GT(o.first_frame_timeout, o.stall_timeout);
    EXPECT_GT(o.max_failed_requests, 0u);
}

// Real CameraManager; this machine has no camera with this id.
TEST(LibcameraSource, NoMatchingCameraIsAClearErrorNotACrash)
{
    CapturedLog log;
    const LibcameraOptions options{.camera = std::string("stemd-no-such-camera")};
    LibcameraSource source(options, log.logger);
    EXPECT_EQ(source.name(), "libcamera:stemd-no-such-camera");
    stemd::test::expect_unopenable(source);
    EXPECT_EQ(source.libcamera_counters().errors, 1u);
    const std::string text = log.text();
    EXPECT_NE(text.find("libcamera:stemd-no-such-camera: source.libcamera_camera: no camera matches "
                        "'stemd-no-such-camera' (cameras: "),
              std::string::npos)
        << text;
}

TEST(LibcameraSource, IndexBeyondTheCamerasIsAClearError)
{
    CapturedLog log;
    // Built whole: GCC 12 at -O3 warns (maybe-uninitialized) on assigning a
    // two-character literal to a default-constructed member string.
    const LibcameraOptions options{.camera = std::string("99")};
    LibcameraSource source(options, log.logger);
    EXPECT_FALSE(source.open());
    const std::string text = log.text();
    EXPECT_NE(text.find("libcamera:99: source.libcamera_camera: no camera with index 99 (cameras: "),
              std::string::npos)
        << text;
}

#else

TEST(LibcameraSource, NotBuilt)
{
    GTEST_SKIP() << "libcamera-dev was missing when CMake configured: the libcamera source is not built";
}

#endif
