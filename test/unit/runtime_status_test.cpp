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

// The status line from `before` to `now` shows `interval`, and the
// summary at `now` shows `total`.
void expect_interval_and_total(const StatusSnapshot& now, const StatusSnapshot& before, const std::string& interval,
                               const std::string& total)
{
    const std::string line = format_status(now, before);
    EXPECT_NE(line.find(interval), std::string::npos) << line;
    const std::string summary = format_summary(now, 2.0);
    EXPECT_NE(summary.find(total), std::string::npos) << summary;
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
    expect_interval_and_total(now, before, "source: timeouts 5, errors 3, reopens 1",
                              "source: timeouts 7, errors 4, reopens 1");
}

// A camera trigger: pulses sent, periods skipped for lateness, and pulses
// that did not go out (the GPIO lines down or being reopened); nothing of
// it without a trigger line.
TEST(Status, TheCameraTriggersPulsesAreShownOnlyWithATrigger)
{
    StatusSnapshot before;
    before.t_ns = 1'000'000'000;
    before.trigger = true;
    before.trigger_pulses = 30;
    before.trigger_failed = 1;
    StatusSnapshot now = before;
    now.t_ns = 2'000'000'000;
    now.trigger_pulses = 58;
    now.trigger_late = 1;
    now.trigger_failed = 2;
    expect_interval_and_total(now, before, "trigger: pulses 28, late 1, failed 1", "trigger: pulses 58, late 1, failed 2");
    now.trigger = false;
    EXPECT_EQ(format_status(now, before).find("trigger"), std::string::npos);
    EXPECT_EQ(format_summary(now, 2.0).find("trigger"), std::string::npos);
}

// The optional files' lines through the writer thread: written and lost.
TEST(Status, TheFilesLinesWrittenAndLostAreShownOnlyWithFiles)
{
    StatusSnapshot before;
    before.t_ns = 1'000'000'000;
    before.files = true;
    before.file_lines_written = 100;
    StatusSnapshot now = before;
    now.t_ns = 2'000'000'000;
    now.file_lines_written = 130;
    now.file_lines_lost = 4;
    expect_interval_and_total(now, before, "files: lines written 30, lost 4", "files: lines written 130, lost 4");
    now.files = false;
    EXPECT_EQ(format_status(now, before).find("files:"), std::string::npos);
}

// A live odometer's frames and the samples refused while the machine
// reversed; nothing for a recording's or a constant-speed odometer.
TEST(Status, ALiveOdometersFramesAndReversingAreShown)
{
    StatusSnapshot before = with_actuation();
    before.t_ns = 1'000'000'000;
    before.odometry_can = true;
    before.rx_odometry = 500;
    before.odometry_going_back = 20;
    StatusSnapshot now = before;
    now.t_ns = 2'000'000'000;
    now.rx_odometry = 600;
    now.odometry_going_back = 45;
    expect_interval_and_total(now, before, "odometry: rx 100, going back 25", "odometry: rx 600, going back 45");
    now.odometry_can = before.odometry_can = false;
    now.odometry_encoder = true;
    expect_interval_and_total(now, before, "odometry: going back 25", "odometry: going back 45");
    now.odometry_encoder = false;
    EXPECT_EQ(format_status(now, before).find("odometry:"), std::string::npos);
}

// Plants no ready tool covered are part of not_treated, and shown apart.
TEST(Status, PlantsNoReadyToolCoveredAreShown)
{
    StatusSnapshot before = with_actuation();
    before.t_ns = 1'000'000'000;
    before.not_treated = 5;
    before.not_ready = 2;
    StatusSnapshot now = before;
    now.t_ns = 2'000'000'000;
    now.not_treated = 9;
    now.not_ready = 5;
    expect_interval_and_total(now, before, "not_treated 4 (tools not ready 3)", "not_treated 9 (tools not ready 5)");
}

// The tool controller's last TOOL_STATUS, once one came: a state, the same
// in the interval's line and the summary.
TEST(Status, TheToolControllersLastStatusIsShownOnceItSpoke)
{
    StatusSnapshot s = with_actuation();
    EXPECT_EQ(format_status(s, StatusSnapshot{}).find("tool controller:"), std::string::npos);
    s.tool_status = true;
    s.tools_ready_mask = 0x0008;
    s.tool_error_code = 4;
    s.tool_status_age_ms = 42.4;
    expect_interval_and_total(s, StatusSnapshot{}, "tool controller: ready 0x0008, error 4 (ACTUATOR_FAULT), TOOL_STATUS 42 ms ago",
                              "tool controller: ready 0x0008, error 4 (ACTUATOR_FAULT), TOOL_STATUS 42 ms ago");
    s.tool_error_code = 77;
    EXPECT_NE(format_status(s, StatusSnapshot{}).find("error 77 (unnamed)"), std::string::npos);
}

// A SocketCAN interface's frames late on the wire or never reported on it,
// the sends that waited, and the controller's error states; nothing for a
// CAN log.
TEST(Status, TheCanInterfacesWireAndControllerAreShown)
{
    StatusSnapshot before = with_actuation();
    before.t_ns = 1'000'000'000;
    before.can_interface = true;
    before.can_tx_late = 1;
    before.can_tx_waits = 10;
    StatusSnapshot now = before;
    now.t_ns = 2'000'000'000;
    now.can_tx_late = 3;
    now.can_tx_unconfirmed = 1;
    now.can_tx_waits = 17;
    now.can_bus_off = 1;
    now.can_error_passive = 2;
    expect_interval_and_total(now, before,
                              "can: late on the wire 2, unconfirmed 1, waited 7, bus_off 1, error_passive 2",
                              "can: late on the wire 3, unconfirmed 1, waited 17, bus_off 1, error_passive 2");
    now.can_interface = false;
    EXPECT_EQ(format_status(now, before).find("can:"), std::string::npos);
}

TEST(Status, ToolTimingPerToolThatFiredOrLeads)
{
    StatusSnapshot s = with_actuation();
    s.n_tools = 2;
    s.tool_timing[0] = {.tool_id = 3, .learning = true, .latency_ms = 40.0, .fired = 12, .lag_mean_mm = 55.6,
                        .lag_p95_mm = 57.0, .lag_mean_ms = 40.1, .lag_p95_ms = 40.5, .strike_p95_mm = 1.25};
    s.tool_timing[1] = {.tool_id = 5};   // never fired, no latency: not shown
    s.rx_tool_fired = 13;
    s.fired_unmatched = 1;
    s.compensation_misses = 2;
    const std::string line = format_status(s, StatusSnapshot{});
    EXPECT_NE(line.find("| tool 3: fired 12, lag 55.6 mm 40.1 ms (p95 57.0 mm 40.50 ms), strike p95 1.25 mm, "
                        "latency 40.0 ms learned"),
              std::string::npos)
        << line;
    EXPECT_EQ(line.find("tool 5"), std::string::npos) << line;
    EXPECT_NE(line.find("fired_unmatched 1, compensation_misses 2"), std::string::npos) << line;
    EXPECT_NE(format_summary(s, 2.0).find("| tool 3: fired 12"), std::string::npos);
}

TEST(Status, LatencyChangesAreNamedOncePerChange)
{
    StatusSnapshot before = with_actuation(), now = with_actuation();
    before.n_tools = now.n_tools = 2;
    before.tool_timing[0] = {.tool_id = 3, .learning = true, .latency_ms = 0.0};
    before.tool_timing[1] = {.tool_id = 4, .latency_ms = 12.0};
    now.tool_timing = before.tool_timing;
    EXPECT_EQ(format_latency_changes(now, before), "");
    now.tool_timing[0].latency_ms = 39.75;
    EXPECT_EQ(format_latency_changes(now, before), "tool 3: latency 39.8 ms (learned, was 0.0 ms)");
}

TEST(Status, GnssQualityIsShownAndAnEstimateOverTheMaximumIsNamed)
{
    StatusSnapshot s = with_actuation();
    EXPECT_EQ(format_status(s, StatusSnapshot{}).find("gnss:"), std::string::npos);
    s.gnss = true;
    s.gnss_mode = 3;
    s.gnss_status = 3;
    s.gnss_eph_mm = 14;
    s.gnss_max_eph_mm = 100;
    s.gnss_fixes = 812;
    s.gnss_degraded = 2;
    const std::string line = format_status(s, StatusSnapshot{});
    EXPECT_NE(line.find("gnss: 3d rtk_fixed, eph 14.0 mm, fixes 812, degraded 2"), std::string::npos) << line;
    s.gnss_mode = 2;
    s.gnss_status = 2;
    s.gnss_eph_mm = 2400;
    const std::string over = format_summary(s, 1.0);
    EXPECT_NE(over.find("gnss: 2d dgps, eph 2400.0 mm over gnss.max_eph_mm, fixes 812"), std::string::npos) << over;
    s.gnss_mode = 0;
    s.gnss_status = 0;
    s.gnss_eph_mm = -1;
    const std::string none = format_status(s, StatusSnapshot{});
    EXPECT_NE(none.find("gnss: none none, eph unknown"), std::string::npos) << none;
}

// With the in-box model, the weed targets it added beside the plants'
// stems, by kind, and the cells its budget left unclassified: the line the
// interval's, the summary the whole run's.
TEST(Status, TheModelsWeedTargetsAreShownByKind)
{
    StatusSnapshot before = with_actuation();
    before.t_ns = 1'000'000'000;
    before.class_model = true;
    before.weed_parts = 3;
    before.stemless_weeds = 1;
    before.weed_cover = 10;
    before.cells_over_budget = 500;
    before.frames_over_budget = 2;
    StatusSnapshot now = before;
    now.t_ns = 2'000'000'000;
    now.weed_parts = 5;
    now.stemless_weeds = 4;
    now.weed_cover = 17;
    now.cells_over_budget = 800;
    now.frames_over_budget = 3;
    expect_interval_and_total(now, before, "weed targets: parts 2, stemless 3, cover 7 | cells over budget 300 in 1 frames",
                              "weed targets: parts 5, stemless 4, cover 17 | cells over budget 800 in 3 frames");
    now.class_model = false;
    EXPECT_EQ(format_status(now, before).find("weed targets"), std::string::npos) << "another provider adds none";
}
