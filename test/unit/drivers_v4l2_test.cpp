// The V4L2 source without a device: format conversion into a preallocated
// slot, capture times, the reopen backoff (injected times), and clear errors
// for a missing device or a file that is not a V4L2 device.
#include <linux/videodev2.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <sstream>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include "v4l2/v4l2_source.hpp"
#include "captured_log.hpp"
#include "frame_source_test_util.hpp"

using namespace stemd::drivers;
using namespace std::chrono_literals;

namespace {

// BT.601 limited range, the inverse of OpenCV's COLOR_YUV2BGR_YUYV.
std::vector<std::uint8_t> yuyv_of(cv::Vec3b bgr, int width, int height, std::size_t bytesperline)
{
    const double b = bgr[0], g = bgr[1], r = bgr[2];
    const auto y = static_cast<std::uint8_t>(16 + 0.257 * r + 0.504 * g + 0.098 * b + 0.5);
    const auto u = static_cast<std::uint8_t>(128 - 0.148 * r - 0.291 * g + 0.439 * b + 0.5);
    const auto v = static_cast<std::uint8_t>(128 + 0.439 * r - 0.368 * g - 0.071 * b + 0.5);
    std::vector<std::uint8_t> out(bytesperline * static_cast<std::size_t>(height), 0);
    for (int row = 0; row < height; ++row)
        for (int x = 0; x < width; x += 2) {
            std::uint8_t* q = out.data() + static_cast<std::size_t>(row) * bytesperline + 2 * static_cast<std::size_t>(x);
            q[0] = y, q[1] = u, q[2] = y, q[3] = v;
        }
    return out;
}

void expect_near(cv::Vec3b got, cv::Vec3b want, int tolerance)
{
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(got[c], want[c], tolerance) << "channel " << c;
}

using stemd::test::CapturedLog;

}  // namespace

TEST(V4l2Convert, YuyvIntoPreallocatedSlotKeepsItsBufferAndColours)
{
    const cv::Size size(64, 8);
    const std::size_t bpl = 64 * 2 + 32;  // padded rows
    const cv::Vec3b green{40, 150, 60};
    const auto bytes = yuyv_of(green, size.width, size.height, bpl);
    cv::Mat slot(size, CV_8UC3, cv::Scalar::all(0));
    const std::uint8_t* before = slot.data;
    ASSERT_EQ(convert_to_bgr(bytes.data(), bytes.size(), bpl, size, V4l2PixelFormat::yuyv, slot), ConvertStatus::ok);
    EXPECT_EQ(slot.data, before);
    expect_near(slot.at<cv::Vec3b>(0, 0), green, 3);
    expect_near(slot.at<cv::Vec3b>(7, 63), green, 3);
}

TEST(V4l2Convert, YuyvKeepsRedAndBlueApart)
{
    const cv::Size size(16, 2);
    const cv::Vec3b brown{45, 80, 125};
    const auto bytes = yuyv_of(brown, size.width, size.height, 32);
    cv::Mat slot(size, CV_8UC3);
    ASSERT_EQ(convert_to_bgr(bytes.data(), bytes.size(), 32, size, V4l2PixelFormat::yuyv, slot), ConvertStatus::ok);
    const cv::Vec3b px = slot.at<cv::Vec3b>(1, 5);
    EXPECT_GT(px[2], px[0] + 60) << "red must stay in channel 2 (BGR)";
}

TEST(V4l2Convert, Bgr24WithRowPaddingIsCopied)
{
    const cv::Size size(5, 3);
    const std::size_t bpl = 5 * 3 + 1;
    std::vector<std::uint8_t> bytes(bpl * 3, 0xEE);
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 5; ++x)
            for (int c = 0; c < 3; ++c)
                bytes[static_cast<std::size_t>(y) * bpl + static_cast<std::size_t>(x * 3 + c)] =
                    static_cast<std::uint8_t>(10 * y + x + 100 * c);
    cv::Mat slot(size, CV_8UC3, cv::Scalar::all(0));
    const std::uint8_t* before = slot.data;
    ASSERT_EQ(convert_to_bgr(bytes.data(), bytes.size(), bpl, size, V4l2PixelFormat::bgr24, slot), ConvertStatus::ok);
    EXPECT_EQ(slot.data, before);
    EXPECT_EQ(slot.at<cv::Vec3b>(2, 4), cv::Vec3b(24, 124, 224));
    EXPECT_EQ(slot.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 100, 200));
}

TEST(V4l2Convert, GreyIsExpandedToEqualChannels)
{
    const cv::Size size(4, 2);
    const std::vector<std::uint8_t> bytes{1, 2, 3, 4, 50, 60, 70, 80};
    cv::Mat slot(size, CV_8UC3, cv::Scalar::all(0));
    const std::uint8_t* before = slot.data;
    ASSERT_EQ(convert_to_bgr(bytes.data(), bytes.size(), 4, size, V4l2PixelFormat::grey, slot), ConvertStatus::ok);
    EXPECT_EQ(slot.data, before);
    EXPECT_EQ(slot.at<cv::Vec3b>(1, 2), cv::Vec3b(70, 70, 70));
}

TEST(V4l2Convert, WrongSlotOrShortBufferIsReportedNotWritten)
{
    const cv::Size size(8, 4);
    const auto bytes = yuyv_of({1, 2, 3}, 8, 4, 16);
    cv::Mat small(4, 4, CV_8UC3, cv::Scalar::all(7));
    EXPECT_EQ(convert_to_bgr(bytes.data(), bytes.size(), 16, size, V4l2PixelFormat::yuyv, small),
              ConvertStatus::bad_size);
    EXPECT_EQ(small.at<cv::Vec3b>(0, 0), cv::Vec3b(7, 7, 7));
    cv::Mat grey_slot(size, CV_8UC1);
    EXPECT_EQ(convert_to_bgr(bytes.data(), bytes.size(), 16, size, V4l2PixelFormat::yuyv, grey_slot),
              ConvertStatus::bad_size);
    cv::Mat slot(size, CV_8UC3, cv::Scalar::all(7));
    EXPECT_EQ(convert_to_bgr(bytes.data(), bytes.size() - 1, 16, size, V4l2PixelFormat::yuyv, slot),
              ConvertStatus::corrupt);
    EXPECT_EQ(slot.at<cv::Vec3b>(3, 7), cv::Vec3b(7, 7, 7));
}

TEST(V4l2Convert, PixelFormatNames)
{
    EXPECT_EQ(parse_v4l2_pixel_format("yuyv"), V4l2PixelFormat::yuyv);
    EXPECT_EQ(parse_v4l2_pixel_format("bgr24"), V4l2PixelFormat::bgr24);
    EXPECT_EQ(parse_v4l2_pixel_format("grey"), V4l2PixelFormat::grey);
    EXPECT_FALSE(parse_v4l2_pixel_format("mjpeg"));
    EXPECT_EQ(v4l2_fourcc_of(V4l2PixelFormat::bgr24), V4L2_PIX_FMT_BGR24);
    EXPECT_EQ(v4l2_fourcc_of(V4l2PixelFormat::yuyv), V4L2_PIX_FMT_YUYV);
    EXPECT_EQ(v4l2_fourcc_of(V4l2PixelFormat::grey), V4L2_PIX_FMT_GREY);
}

TEST(V4l2Time, MonotonicTimestampIsConvertedToNanoseconds)
{
    v4l2_buffer buf{};
    buf.flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    buf.timestamp.tv_sec = 12;
    buf.timestamp.tv_usec = 345'678;
    EXPECT_EQ(v4l2_capture_time_ns(buf, 20'000'000'000), 12'345'678'000);
    // Never after the dequeue (nominal timestamps of some drivers).
    EXPECT_EQ(v4l2_capture_time_ns(buf, 12'000'000'000), 12'000'000'000);
}

TEST(V4l2Time, OtherClocksUseTheDequeueTime)
{
    v4l2_buffer buf{};
    buf.flags = V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN;
    buf.timestamp.tv_sec = 12;
    EXPECT_EQ(v4l2_capture_time_ns(buf, 99), 99);
    buf.flags = V4L2_BUF_FLAG_TIMESTAMP_COPY;
    EXPECT_EQ(v4l2_capture_time_ns(buf, 77), 77);
}

// The schedule V4l2Source builds from its options (the shared ReopenBackoff,
// tested on its own in drivers_backoff_test.cpp).
TEST(V4l2Backoff, DoublesUpToTheCapAndStartsOverAfterSuccess)
{
    constexpr std::int64_t ms = 1'000'000;
    const V4l2Options options;
    ReopenBackoff b(options.backoff_initial, options.backoff_max);  // 100 ms .. 5 s
    EXPECT_TRUE(b.due(0));
    b.on_failure(0);
    EXPECT_FALSE(b.due(99 * ms));
    EXPECT_TRUE(b.due(100 * ms));
    std::int64_t t = 100 * ms;
    const std::int64_t expected_delays_ms[] = {200, 400, 800, 1600, 3200, 5000, 5000};
    for (std::int64_t d : expected_delays_ms) {
        b.on_failure(t);
        EXPECT_EQ(b.next_attempt_ns(), t + d * ms);
        EXPECT_FALSE(b.due(t + d * ms - 1));
        t += d * ms;
        EXPECT_TRUE(b.due(t));
    }
    EXPECT_EQ(b.consecutive_failures(), 8u);
    b.on_success();
    EXPECT_EQ(b.consecutive_failures(), 0u);
    EXPECT_EQ(b.current_delay_ns(), 100 * ms);
    b.on_failure(t);
    EXPECT_EQ(b.next_attempt_ns(), t + 100 * ms);
}

TEST(V4l2Source, MissingDeviceIsAClearErrorNotACrash)
{
    CapturedLog log;
    V4l2Options options;
    options.device = "/dev/stemd-no-such-video-device";
    options.clock = [] { return std::int64_t{0}; };
    V4l2Source source(options, log.logger);
    EXPECT_EQ(source.name(), "v4l2:/dev/stemd-no-such-video-device");
    stemd::test::expect_unopenable(source);
    const std::string text = log.text();
    EXPECT_NE(text.find("/dev/stemd-no-such-video-device: cannot open: No such file or directory (errno 2)"),
              std::string::npos)
        << text;
}

TEST(V4l2Source, NotAVideoDeviceIsAClearError)
{
    CapturedLog log;
    V4l2Options options;
    options.device = "/dev/null";
    V4l2Source source(options, log.logger);
    EXPECT_FALSE(source.open());
    const std::string text = log.text();
    EXPECT_NE(text.find("/dev/null: VIDIOC_QUERYCAP (not a V4L2 device?)"), std::string::npos) << text;
    EXPECT_NE(text.find("(errno 25)"), std::string::npos) << text;  // ENOTTY
}
