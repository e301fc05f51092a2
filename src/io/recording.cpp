#include "stemd/io/recording.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/io/csv.hpp"

namespace stemd::io {

bool is_recording_dir(const std::filesystem::path& path)
{
    std::error_code ec;
    return std::filesystem::is_directory(path, ec) && std::filesystem::is_regular_file(path / "frames.csv", ec);
}

bool parse_odom_mm(std::string_view text, double& out)
{
    double value = 0;
    const char* end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, value);
    if (text.empty() || ec != std::errc() || ptr != end || !std::isfinite(value))
        return false;
    out = value;
    return true;
}

std::optional<Recording> read_recording(const std::filesystem::path& dir, std::string& error)
{
    const auto csv_path = dir / "frames.csv";
    auto table = read_csv(csv_path, error);
    if (!table)
        return std::nullopt;
    const std::vector<std::string> fixed{"t_ns", "rgb", "nir", "mask"};
    if (table->header.size() < fixed.size() || !std::equal(fixed.begin(), fixed.end(), table->header.begin())) {
        error = csv_path.string() + ":1: header must start with '" + kFramesCsvHeader + "'";
        return std::nullopt;
    }
    int odom_col = -1, class_col = -1;
    for (std::size_t i = fixed.size(); i < table->header.size(); ++i) {
        const std::string& name = table->header[i];
        int* col = name == kFramesCsvOdomColumn ? &odom_col : name == kFramesCsvClassColumn ? &class_col : nullptr;
        if (col == nullptr) {
            error = csv_path.string() + ":1: unknown column '" + name + "'";
            return std::nullopt;
        }
        if (*col >= 0) {
            error = csv_path.string() + ":1: column '" + name + "' appears twice";
            return std::nullopt;
        }
        *col = static_cast<int>(i);
    }
    Recording rec;
    rec.dir = dir;
    int previous_line = 0;   // 0: no frame yet
    std::int64_t previous_t_ns = 0;
    std::optional<double> last_odom_mm;
    int last_odom_line = 0;
    for (const auto& row : table->rows) {
        const std::string where = csv_path.string() + ":" + std::to_string(row.line) + ": ";
        RecordingFrame frame;
        const std::string& t = row.fields[0];
        const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), frame.t_ns);
        if (ec != std::errc() || end != t.data() + t.size()) {
            error = where + "t_ns '" + t + "' is not an integer";
            return std::nullopt;
        }
        if (frame.t_ns < 0) {
            error = where + "t_ns " + t + " is negative (a capture time is CLOCK_MONOTONIC, never below 0)";
            return std::nullopt;
        }
        if (previous_line > 0 && frame.t_ns <= previous_t_ns) {
            error = where + "t_ns " + t + (frame.t_ns == previous_t_ns ? " repeats" : " is before") + " line " +
                    std::to_string(previous_line) + "'s " + std::to_string(previous_t_ns) +
                    " (t_ns must increase from frame to frame)";
            return std::nullopt;
        }
        // Both are >= 0 here, so the difference cannot overflow.
        if (previous_line > 0 && frame.t_ns - previous_t_ns > kMaxFrameGapNs) {
            error = where + "t_ns " + t + " is " + std::to_string((frame.t_ns - previous_t_ns) / 1'000'000'000) +
                    " s after line " + std::to_string(previous_line) + "'s (at most " +
                    std::to_string(kMaxFrameGapNs / 1'000'000'000) + " s between frames)";
            return std::nullopt;
        }
        frame.rgb = row.fields[1];
        frame.nir = row.fields[2];
        frame.mask = row.fields[3];
        if (frame.rgb.empty() && frame.mask.empty()) {
            error = where + "a frame needs an rgb or a mask path";
            return std::nullopt;
        }
        if (odom_col >= 0) {
            const std::string& odom = row.fields[static_cast<std::size_t>(odom_col)];
            double value = 0;
            if (!odom.empty() && !parse_odom_mm(odom, value)) {
                error = where + "odom_mm '" + odom + "' is not a finite number";
                return std::nullopt;
            }
            if (!odom.empty()) {
                if (std::abs(value) > kMaxOdomMm) {
                    error = where + "odom_mm " + odom + " is beyond +-1e9 mm (1000 km)";
                    return std::nullopt;
                }
                if (last_odom_mm && value < *last_odom_mm) {
                    error = where + "odom_mm " + odom + " is less than line " + std::to_string(last_odom_line) +
                            "'s (the odometer never decreases)";
                    return std::nullopt;
                }
                frame.odom_mm = value;
                last_odom_mm = value;
                last_odom_line = row.line;
            }
        }
        if (class_col >= 0)
            frame.plant_class = row.fields[static_cast<std::size_t>(class_col)];
        previous_t_ns = frame.t_ns;
        previous_line = row.line;
        rec.frames.push_back(std::move(frame));
    }
    return rec;
}

bool load_image(const std::filesystem::path& path, int imread_flags, cv::Mat& out, std::string& error)
{
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) {
        error = path.string() + ": no such file";
        return false;
    }
    try {
        out = cv::imread(path.string(), imread_flags);
    } catch (const cv::Exception& e) {
        error = path.string() + ": cannot decode: " + e.what();
        return false;
    }
    if (out.empty()) {
        error = path.string() + ": cannot decode (corrupt or not an image)";
        return false;
    }
    return true;
}

}  // namespace stemd::io
