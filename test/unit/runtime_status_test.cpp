// The status line and the final summary: what an operator reads.
#include <gtest/gtest.h>

#include "stemd/runtime/status.hpp"

using namespace stemd::runtime;

namespace {

StatusSnapshot with_actuation()
{
    StatusSnapshot s;
    s.t_ns = 2'000'000'000;
    s.frames_in = s.frames_out = 60;
    s.actuation = true;
    s.targets = 4;
    s.sent = 3;
    s.deadline_misses = 1;
    s.send.count = 3;
    s.send.p50_ms = 3.0;
    s.send.p99_ms = 4.25;
    s.send.max_ms = 5.5;
    return s;
}

}  // namespace

TEST(Status, ActuationShowsTheCaptureToSendLatency)
{
    StatusSnapshot before;
    before.t_ns = 1'000'000'000;
    const std::string line = format_status(with_actuation(), before);
    EXPECT_NE(line.find("targets 4, sent 3, deadline_misses 1"), std::string::npos) << line;
    EXPECT_NE(line.find("capture to send p50 3.00 p99 4.25 max 5.50 ms"), std::string::npos) << line;
    const std::string summary = format_summary(with_actuation(), 2.0);
    EXPECT_NE(summary.find("capture to send p50 3.00 p99 4.25 max 5.50 ms"), std::string::npos) << summary;
}

TEST(Status, WithoutActuationThereIsNoSendLatency)
{
    StatusSnapshot s = with_actuation();
    s.actuation = false;
    const std::string line = format_status(s, StatusSnapshot{});
    EXPECT_EQ(line.find("capture to send"), std::string::npos) << line;
    EXPECT_EQ(line.find("targets"), std::string::npos) << line;
}

// A camera unplugged and replugged: the line shows the interval's source
// timeouts, errors and reopens, the summary the whole run's.
TEST(Status, SourceTimeoutsErrorsAndReopensAreShown)
{
    StatusSnapshot before;
    before.t_ns = 1'000'000'000;
    before.source_timeouts = 2;
    before.source_errors = 1;
    StatusSnapshot now = before;
    now.t_ns = 2'000'000'000;
    now.source_timeouts = 7;
    now.source_errors = 4;
    now.source_reopens = 1;
    const std::string line = format_status(now, before);
    EXPECT_NE(line.find("source: timeouts 5, errors 3, reopens 1"), std::string::npos) << line;
    const std::string summary = format_summary(now, 2.0);
    EXPECT_NE(summary.find("source: timeouts 7, errors 4, reopens 1"), std::string::npos) << summary;
}
