// Prometheus text format of the daemon's metrics: every line parses, every
// family is declared once before its samples, histograms are cumulative and
// end in +Inf = _count, and histogram_of reads the daemon's 50 us buckets.
#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "stemd/web/metrics.hpp"

using namespace stemd;

namespace {

struct Sample {
    std::string name, labels;
    double value = 0;
};

// A strict reading of the 0.0.4 text format as format_metrics writes it.
std::vector<Sample> parse(const std::string& text, std::map<std::string, std::string>& types, std::string& error)
{
    static const std::regex help(R"(^# HELP (stemd_[a-z_]+) .+$)");
    static const std::regex type(R"(^# TYPE (stemd_[a-z_]+) (counter|gauge|histogram)$)");
    static const std::regex sample(R"(^(stemd_[a-z_]+)(\{([a-z_]+="[^"]*"(,[a-z_]+="[^"]*")*)\})? ([0-9.eE+-]+|\+Inf)$)");
    std::vector<Sample> out;
    std::istringstream in(text);
    std::string line;
    std::smatch m;
    while (std::getline(in, line)) {
        if (std::regex_match(line, m, type)) {
            if (types.count(m[1]))
                error += "family declared twice: " + line + "\n";
            types[m[1]] = m[2];
        } else if (std::regex_match(line, m, help)) {
        } else if (std::regex_match(line, m, sample)) {
            out.push_back({m[1], m[3], std::stod(m[5])});
            std::string family = m[1];
            for (const char* suffix : {"_bucket", "_sum", "_count"})
                if (!types.count(family) && family.size() > std::strlen(suffix) &&
                    family.ends_with(suffix))
                    family.resize(family.size() - std::strlen(suffix));
            if (!types.count(family))
                error += "sample before its TYPE: " + line + "\n";
        } else {
            error += "unparsable: '" + line + "'\n";
        }
    }
    return out;
}

// The samples of parse(), each by "name{labels}".
std::map<std::string, double> by_key(const std::vector<Sample>& samples)
{
    std::map<std::string, double> out;
    for (const Sample& s : samples)
        out[s.name + "{" + s.labels + "}"] = s.value;
    return out;
}

}  // namespace

TEST(WebMetrics, HistogramOfCountsWholeBucketsBelowEachBound)
{
    runtime::DurationHistogram h;
    h.record(300'000);       // 0.3 ms
    h.record(700'000);       // 0.7 ms
    h.record(3'900'000);     // 3.9 ms
    h.record(250'000'000);   // beyond every bound
    const web::Histogram out = web::histogram_of(h);
    EXPECT_EQ(out.count, 4u);
    EXPECT_NEAR(out.sum_s, 0.0003 + 0.0007 + 0.0039 + 0.25, 1e-12);
    EXPECT_EQ(out.below[0], 1u);   // <= 0.5 ms
    EXPECT_EQ(out.below[1], 2u);   // <= 1 ms
    EXPECT_EQ(out.below[3], 2u);   // <= 3 ms
    EXPECT_EQ(out.below[4], 3u);   // <= 4 ms
    EXPECT_EQ(out.below.back(), 3u) << "200 ms: the overflow is only in +Inf";
}

TEST(WebMetrics, TextFormatParsesAndHistogramsAreConsistent)
{
    web::Metrics m;
    m.frames_in = 100;
    m.frames_out = 98;
    m.ring_full = 2;
    m.actuation = true;
    m.sent = 7;
    m.deadline_miss = 1;
    m.bus_deadline = 1;
    runtime::DurationHistogram h;
    for (int i = 1; i <= 50; ++i)
        h.record(i * 200'000);
    m.capture_to_result = web::histogram_of(h);
    m.cycle_processing = web::histogram_of(h);
    std::map<std::string, std::string> types;
    std::string error;
    const std::vector<Sample> samples = parse(web::format_metrics(m), types, error);
    EXPECT_EQ(error, "");
    EXPECT_EQ(types.at("stemd_frames_in_total"), "counter");
    EXPECT_EQ(types.at("stemd_capture_to_result_seconds"), "histogram");
    EXPECT_EQ(types.at("stemd_thread_cycle_seconds"), "histogram");
    const std::map<std::string, double> value = by_key(samples);
    EXPECT_EQ(value.at("stemd_frames_in_total{}"), 100);
    EXPECT_EQ(value.at("stemd_frames_dropped_total{cause=\"ring_full\"}"), 2);
    EXPECT_EQ(value.at("stemd_targets_total{outcome=\"sent\"}"), 7);
    EXPECT_EQ(value.at("stemd_deadline_misses_total{}"), 2);
    // Each histogram series: cumulative, +Inf = _count.
    for (const std::string& series : {std::string("stemd_capture_to_result_seconds_bucket{"),
                                      std::string("stemd_thread_cycle_seconds_bucket{thread=\"processing\",")}) {
        double previous = -1;
        int buckets = 0;
        for (const Sample& s : samples) {
            const std::string key = s.name + "{" + s.labels;
            if (key.rfind(series, 0) != 0)
                continue;
            EXPECT_GE(s.value, previous) << key;
            previous = s.value;
            ++buckets;
        }
        EXPECT_EQ(buckets, static_cast<int>(web::kBucketUpperNs.size()) + 1) << series;
        EXPECT_EQ(previous, 50) << series << ": +Inf";
    }
    EXPECT_EQ(value.at("stemd_capture_to_result_seconds_count{}"), 50);
    EXPECT_NEAR(value.at("stemd_capture_to_result_seconds_sum{}"), 0.2e-3 * 50 * 51 / 2, 1e-9);
    EXPECT_EQ(value.at("stemd_capture_to_result_seconds_bucket{le=\"0.005\"}"), 24) << "the durations below 5 ms: 0.2 .. 4.8 ms";
}

TEST(WebMetrics, ActuationSeriesOnlyWithActuation)
{
    web::Metrics m;
    const std::string text = web::format_metrics(m);
    EXPECT_EQ(text.find("stemd_targets_total"), std::string::npos);
    EXPECT_EQ(text.find("stemd_capture_to_send_seconds"), std::string::npos);
    m.actuation = true;
    EXPECT_NE(web::format_metrics(m).find("stemd_capture_to_send_seconds_bucket{le=\"+Inf\"} 0"), std::string::npos);
}

TEST(WebMetrics, TriggerAndFileSeriesOnlyWithATriggerAndFiles)
{
    web::Metrics m;
    std::string text = web::format_metrics(m);
    EXPECT_EQ(text.find("stemd_trigger_pulses_total"), std::string::npos);
    EXPECT_EQ(text.find("stemd_file_lines_total"), std::string::npos);
    m.trigger = true;
    m.trigger_pulses = 300;
    m.trigger_late = 2;
    m.trigger_failed = 5;
    m.files = true;
    m.file_lines_written = 812;
    m.file_lines_lost = 3;
    std::map<std::string, std::string> types;
    std::string error;
    const std::map<std::string, double> value = by_key(parse(web::format_metrics(m), types, error));
    EXPECT_EQ(error, "");
    EXPECT_EQ(types.at("stemd_trigger_pulses_total"), "counter");
    EXPECT_EQ(value.at("stemd_trigger_pulses_total{outcome=\"sent\"}"), 300);
    EXPECT_EQ(value.at("stemd_trigger_pulses_total{outcome=\"late\"}"), 2);
    EXPECT_EQ(value.at("stemd_trigger_pulses_total{outcome=\"failed\"}"), 5);
    EXPECT_EQ(types.at("stemd_file_lines_total"), "counter");
    EXPECT_EQ(value.at("stemd_file_lines_total{outcome=\"written\"}"), 812);
    EXPECT_EQ(value.at("stemd_file_lines_total{outcome=\"lost\"}"), 3);
}

TEST(WebMetrics, CanInterfaceSeriesOnlyWithAnInterface)
{
    web::Metrics m;
    m.actuation = true;
    EXPECT_EQ(web::format_metrics(m).find("stemd_can_"), std::string::npos);
    m.can_interface = true;
    m.can_tx_late = 2;
    m.can_tx_unconfirmed = 1;
    m.can_tx_waits = 40;
    m.can_bus_off = 3;
    m.can_error_passive = 4;
    std::map<std::string, std::string> types;
    std::string error;
    const std::map<std::string, double> value = by_key(parse(web::format_metrics(m), types, error));
    EXPECT_EQ(error, "");
    EXPECT_EQ(types.at("stemd_can_frames_total"), "counter");
    EXPECT_EQ(value.at("stemd_can_frames_total{outcome=\"late\"}"), 2);
    EXPECT_EQ(value.at("stemd_can_frames_total{outcome=\"unconfirmed\"}"), 1);
    EXPECT_EQ(value.at("stemd_can_send_waits_total{}"), 40);
    EXPECT_EQ(value.at("stemd_can_controller_events_total{state=\"bus_off\"}"), 3);
    EXPECT_EQ(value.at("stemd_can_controller_events_total{state=\"error_passive\"}"), 4);
}

TEST(WebMetrics, ClassProviderSeriesOnlyWithTheirProvider)
{
    web::Metrics m;
    m.bad_class = 3;
    std::string text = web::format_metrics(m);
    EXPECT_NE(text.find("stemd_bad_class_plants_total 3\n"), std::string::npos) << text;
    EXPECT_EQ(text.find("stemd_weed_targets_total"), std::string::npos);
    EXPECT_EQ(text.find("stemd_classifier_cells_over_budget_total"), std::string::npos);
    EXPECT_EQ(text.find("stemd_class_timeouts_total"), std::string::npos);

    m.class_model = true;
    m.weed_parts = 4;
    m.stemless_weeds = 5;
    m.weed_cover = 6;
    m.cells_over_budget = 700;
    m.frames_over_budget = 2;
    std::map<std::string, std::string> types;
    std::string error;
    std::map<std::string, double> value = by_key(parse(web::format_metrics(m), types, error));
    EXPECT_EQ(error, "");
    EXPECT_EQ(types.at("stemd_weed_targets_total"), "counter");
    EXPECT_EQ(value.at("stemd_weed_targets_total{kind=\"part\"}"), 4);
    EXPECT_EQ(value.at("stemd_weed_targets_total{kind=\"stemless\"}"), 5);
    EXPECT_EQ(value.at("stemd_weed_targets_total{kind=\"cover\"}"), 6);
    EXPECT_EQ(value.at("stemd_classifier_cells_over_budget_total{}"), 700);
    EXPECT_EQ(value.at("stemd_classifier_frames_over_budget_total{}"), 2);
    EXPECT_EQ(value.count("stemd_class_maps_total{}"), 0u);

    m.class_model = false;
    m.class_socket = true;
    m.class_maps = 90;
    m.class_timeouts = 7;
    m.class_bad_messages = 1;
    m.class_peers = 2;
    types.clear();
    value = by_key(parse(web::format_metrics(m), types, error));
    EXPECT_EQ(error, "");
    EXPECT_EQ(value.at("stemd_class_maps_total{}"), 90);
    EXPECT_EQ(value.at("stemd_class_timeouts_total{}"), 7);
    EXPECT_EQ(value.at("stemd_class_bad_messages_total{}"), 1);
    EXPECT_EQ(value.at("stemd_class_peers_total{}"), 2);
    EXPECT_EQ(value.count("stemd_weed_targets_total{kind=\"part\"}"), 0u);
}
