#include "stemd/io/recording_writer.hpp"

#include <charconv>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <system_error>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>


namespace stemd::io {

namespace {

std::string errno_text(int err) { return std::generic_category().message(err); }

}  // namespace

std::string frames_csv_header(const RecordingColumns& columns)
{
    std::string header = kFramesCsvHeader;
    if (columns.odom_mm)
        header += std::string(",") + kFramesCsvOdomColumn;
    if (columns.plant_class)
        header += std::string(",") + kFramesCsvClassColumn;
    return header;
}

bool RecordingWriter::open(const std::filesystem::path& dir, const RecordingWriterOptions& options, std::string& error)
{
    dir_ = dir;
    columns_ = options.columns;
    png_params_.clear();
    if (options.png_compression_level >= 0)
        png_params_ = {cv::IMWRITE_PNG_COMPRESSION, options.png_compression_level};
    frames_written_ = 0;
    std::vector<const char*> folders{"rgb"};
    if (columns_.nir)
        folders.push_back("nir");
    if (columns_.mask)
        folders.push_back("mask");
    if (columns_.plant_class)
        folders.push_back("class");
    for (const char* folder : folders) {
        std::error_code ec;
        std::filesystem::create_directories(dir_ / folder, ec);
        if (ec) {
            error = (dir_ / folder).string() + ": cannot create directory: " + ec.message();
            return false;
        }
    }
    const std::filesystem::path csv_path = dir_ / "frames.csv";
    if (const int err = csv_.open(csv_path.c_str())) {
        error = csv_path.string() + ": cannot create: " + errno_text(err);
        return false;
    }
    if (const int err = csv_.write(frames_csv_header(columns_) + "\n")) {
        error = csv_path.string() + ": cannot write: " + errno_text(err);
        return false;
    }
    return true;
}

bool RecordingWriter::write_png(std::string_view folder, const cv::Mat& image, std::string& relative, std::string& error)
{
    char name[48];
    std::snprintf(name, sizeof name, "%.*s/%06" PRIu64 ".png", static_cast<int>(folder.size()), folder.data(),
                  frames_written_);
    relative = name;
    const std::filesystem::path path = dir_ / relative;
    // Encoded in memory and written with our own write(2), so that a disk
    // error reaches the caller with its errno.
    try {
        if (!cv::imencode(".png", image, png_bytes_, png_params_)) {
            error = path.string() + ": cannot encode as PNG";
            return false;
        }
    } catch (const cv::Exception& e) {
        error = path.string() + ": cannot encode as PNG: " + e.what();
        return false;
    }
    base::RecordFile file;
    if (const int err = file.open(path.c_str())) {
        error = path.string() + ": cannot create: " + errno_text(err);
        return false;
    }
    if (const int err = file.write({reinterpret_cast<const char*>(png_bytes_.data()), png_bytes_.size()})) {
        error = path.string() + ": cannot write: " + errno_text(err);
        return false;
    }
    return true;
}

bool RecordingWriter::append(const FrameToWrite& frame, std::string& error)
{
    auto where = [&] { return (dir_ / "frames.csv").string() + ": frame " + std::to_string(frames_written_) + ": "; };
    if (!csv_.is_open()) {
        error = where() + "the recording is not open";
        return false;
    }
    if ((!frame.nir.empty() && !columns_.nir) || (!frame.mask.empty() && !columns_.mask) ||
        (frame.odom_mm && !columns_.odom_mm) || (!frame.plant_class.empty() && !columns_.plant_class)) {
        error = where() + "has a value for a column this recording was not opened with";
        return false;
    }
    if (frame.bgr.empty() && frame.mask.empty()) {
        error = where() + "a frame needs an rgb or a mask image";
        return false;
    }
    if (frame.odom_mm && !std::isfinite(*frame.odom_mm)) {
        error = where() + "odom_mm is not a finite number";
        return false;
    }
    std::string rgb, nir, mask, plant_class;
    if ((!frame.bgr.empty() && !write_png("rgb", frame.bgr, rgb, error)) ||
        (!frame.nir.empty() && !write_png("nir", frame.nir, nir, error)) ||
        (!frame.mask.empty() && !write_png("mask", frame.mask, mask, error)) ||
        (!frame.plant_class.empty() && !write_png("class", frame.plant_class, plant_class, error)))
        return false;

    // The names are ours and need no CSV quoting.
    char number[32];
    row_.clear();
    row_.append(number, std::to_chars(number, number + sizeof number, frame.t_ns).ptr);
    row_ += ',' + rgb + ',' + nir + ',' + mask;
    if (columns_.odom_mm) {
        row_ += ',';
        // Shortest text that reads back as the same double.
        if (frame.odom_mm)
            row_.append(number, std::to_chars(number, number + sizeof number, *frame.odom_mm).ptr);
    }
    if (columns_.plant_class)
        row_ += ',' + plant_class;
    row_ += '\n';
    if (const int err = csv_.write(row_)) {
        error = (dir_ / "frames.csv").string() + ": cannot write: " + errno_text(err);
        return false;
    }
    last_written_ = {.t_ns = frame.t_ns,
                     .rgb = std::move(rgb),
                     .nir = std::move(nir),
                     .mask = std::move(mask),
                     .odom_mm = frame.odom_mm,
                     .plant_class = std::move(plant_class)};
    ++frames_written_;
    return true;
}

}  // namespace stemd::io
