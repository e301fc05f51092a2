#include "stemd/io/recording.hpp"

#include <charconv>
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

std::optional<Recording> read_recording(const std::filesystem::path& dir, std::string& error)
{
    const auto csv_path = dir / "frames.csv";
    auto table = read_csv(csv_path, error);
    if (!table)
        return std::nullopt;
    const std::vector<std::string> expected{"t_ns", "rgb", "nir", "mask"};
    if (table->header != expected) {
        error = csv_path.string() + ":1: header must be exactly '" + kFramesCsvHeader + "'";
        return std::nullopt;
    }
    Recording rec;
    rec.dir = dir;
    for (const auto& row : table->rows) {
        const std::string where = csv_path.string() + ":" + std::to_string(row.line) + ": ";
        RecordingFrame frame;
        const std::string& t = row.fields[0];
        const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), frame.t_ns);
        if (ec != std::errc() || end != t.data() + t.size()) {
            error = where + "t_ns '" + t + "' is not an integer";
            return std::nullopt;
        }
        frame.rgb = row.fields[1];
        frame.nir = row.fields[2];
        frame.mask = row.fields[3];
        if (frame.rgb.empty() && frame.mask.empty()) {
            error = where + "a frame needs an rgb or a mask path";
            return std::nullopt;
        }
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
