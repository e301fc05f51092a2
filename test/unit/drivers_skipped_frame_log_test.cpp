// The camera backends' warning for skipped frames: the first at once, then
// at most one a second, each counting the ones left out.
#include "stemd/drivers/skipped_frame_log.hpp"

#include <string>

#include <gtest/gtest.h>

#include "captured_log.hpp"

namespace {

using stemd::drivers::SkippedFrameLog;

constexpr std::int64_t kSecondNs = 1'000'000'000;

std::size_t lines(const std::string& text)
{
    std::size_t n = 0;
    for (const char c : text)
        n += c == '\n';
    return n;
}

TEST(SkippedFrameLog, TheFirstIsLoggedAtOnceThenOneASecondWithTheCountLeftOut)
{
    stemd::test::CapturedLog log;
    SkippedFrameLog skipped;
    const std::int64_t t0 = 5 * kSecondNs;
    skipped.warn(*log.logger, t0, "{}: frame {} corrupt", "/dev/video0", 1);
    EXPECT_NE(log.text().find("/dev/video0: frame 1 corrupt; skipped (0 more skipped frames not logged since the "
                              "last warning)"),
              std::string::npos)
        << log.text();
    for (int i = 2; i <= 30; ++i)   // 30 fps: the rest of that second
        skipped.warn(*log.logger, t0 + (i - 1) * kSecondNs / 30, "{}: frame {} corrupt", "/dev/video0", i);
    EXPECT_EQ(lines(log.text()), 1u) << log.text();
    skipped.warn(*log.logger, t0 + kSecondNs, "{}: frame {} corrupt", "/dev/video0", 31);
    EXPECT_EQ(lines(log.text()), 2u);
    EXPECT_NE(log.text().find("frame 31 corrupt; skipped (29 more skipped frames not logged since the last warning)"),
              std::string::npos)
        << log.text();
}

TEST(SkippedFrameLog, AWrongSizeNamesTheFrameAndTheSlot)
{
    stemd::test::CapturedLog log;
    SkippedFrameLog skipped;
    const cv::Mat slot(966, 1296, CV_8UC3);
    skipped.wrong_size(*log.logger, kSecondNs, "libcamera:cam0", {640, 480}, slot);
    EXPECT_NE(log.text().find("libcamera:cam0: frame is 640x480, the slot is 1296x966 type 16; skipped (0 more"),
              std::string::npos)
        << log.text();
}

}  // namespace
