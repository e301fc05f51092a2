// What every camera source does when its device cannot be opened.
#pragma once

#include <chrono>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "stemd/drivers/frame_source.hpp"

namespace stemd::test {

// open() fails and leaves the source failed; start() and next() refuse,
// stop() is harmless, and the one failure is counted, no frame delivered.
template <class Source>
void expect_unopenable(Source& source)
{
    EXPECT_FALSE(source.open());
    EXPECT_EQ(source.state(), Source::State::failed);
    EXPECT_FALSE(source.start());
    drivers::Frame frame;
    frame.bgr = cv::Mat(480, 640, CV_8UC3);
    EXPECT_EQ(source.next(frame, std::chrono::milliseconds(10)), drivers::NextStatus::failed);
    source.stop();
    EXPECT_EQ(source.counters().errors, 1u);
    EXPECT_EQ(source.counters().delivered, 0u);
}

}  // namespace stemd::test
