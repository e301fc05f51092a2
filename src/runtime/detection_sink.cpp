#include "stemd/runtime/detection_sink.hpp"

#include <cerrno>
#include <cstdio>
#include <string>

namespace stemd::runtime {

namespace {

// The image column as stemd-detect writes it (io::csv_field), into `out`
// without allocating: quoted when it holds a comma, a quote or a line break.
std::size_t csv_field(std::string_view value, char* out, std::size_t capacity)
{
    const bool quote = value.find_first_of(",\"\r\n") != std::string_view::npos;
    std::size_t n = 0;
    auto put = [&](char c) {
        if (n + 1 < capacity)
            out[n++] = c;
    };
    if (quote)
        put('"');
    for (const char c : value) {
        if (c == '"')
            put('"');
        put(c);
    }
    if (quote)
        put('"');
    return n;
}

}  // namespace

DetectionSink::DetectionSink(std::shared_ptr<spdlog::logger> log) : log_(log), csv_("detections CSV", log) {}

bool DetectionSink::open_csv(const std::filesystem::path& path)
{
    return csv_.open(path, std::string(kCsvHeader) + "\n");
}

bool DetectionSink::consume(const FrameResult& result, std::int64_t latency_ns)
{
    const vision::Detections& d = result.detections;
    if (log_->should_log(spdlog::level::debug)) {
        std::size_t from_leaves = 0;
        for (const vision::Plant& p : d.plants)
            from_leaves += p.method == vision::StemMethod::leaves;
        log_->debug("frame {} {}: {} plants ({} from leaves), latency {:.2f} ms, pipeline {:.2f} ms", result.seq,
                    result.name.view(), d.plants.size(), from_leaves, latency_ns / 1e6, result.pipeline_ns / 1e6);
    }
    if (!csv_.is_open())
        return true;
    char image[2 * drivers::FrameName::kCapacity + 3];
    const std::size_t image_len = csv_field(result.name.view(), image, sizeof image);
    char line[sizeof image + 160];
    static_assert(sizeof line <= RecordWriter::kLineBytes);
    bool all_written = true;
    for (std::size_t i = 0; i < d.plants.size(); ++i) {
        const vision::Plant& p = d.plants[i];
        if (!p.has_stem)
            continue;   // grass or too unsure: nothing to strike, as stemd-detect
        // Rows and number formatting as stemd-detect ("%.3f" of the floats);
        // to_string() returns views of literals, so nothing is allocated.
        const std::string_view method = vision::to_string(p.method);
        const std::string_view estimator = vision::to_string(p.estimator);
        const int n = std::snprintf(line, sizeof line, "%lld,%.*s,%zu,%.3f,%.3f,%.*s,%zu,%d,%.*s,%.3f\n",
                                    static_cast<long long>(result.t_recorded_ns), static_cast<int>(image_len), image,
                                    i, p.stem.x, p.stem.y, static_cast<int>(method.size()), method.data(),
                                    p.leaves.size(), p.area_px, static_cast<int>(estimator.size()), estimator.data(),
                                    p.confidence);
        const bool written = n >= 0 && static_cast<std::size_t>(n) < sizeof line
                                 ? csv_.write({line, static_cast<std::size_t>(n)})
                                 : csv_.lose(EOVERFLOW);   // a 1e300 stem would not fit: never written half
        all_written = written && all_written;
    }
    return all_written;
}

}  // namespace stemd::runtime
