// Writes a recording directory (frames.csv and its PNGs, the format of
// recording.hpp) one frame at a time, under the names the tools have always
// used: rgb/NNNNNN.png, nir/, mask/, class/ (NNNNNN: the frame's index, at
// least six digits). A frame's PNGs are written before its row, and the row
// goes out whole with one write(2) (base::RecordFile), so a kill leaves
// frames.csv ending on a complete row that names files which exist.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "stemd/base/record_file.hpp"
#include "stemd/io/recording.hpp"

namespace stemd::io {

// Which images and optional columns a recording holds. rgb, nir and mask
// are always in the header (recording.hpp's fixed columns); nir and mask
// say whether their images are written at all.
struct RecordingColumns {
    bool nir = false;
    bool mask = false;
    bool odom_mm = false;       // the odom_mm column
    bool plant_class = false;   // the class column (class/NNNNNN.png)
};

// frames.csv's header line (without the newline) for `columns`.
std::string frames_csv_header(const RecordingColumns& columns);

// One frame to append. The cv::Mat headers share the caller's pixels. Every
// member has an initializer, so designated initializers may leave any out.
// An empty image leaves its field empty; an image for a column the writer
// was not opened with is an error rather than silently lost.
struct FrameToWrite {
    std::int64_t t_ns = 0;
    cv::Mat bgr{};                   // 8-bit colour; rgb or mask is needed
    cv::Mat nir{};                   // 8-bit grey
    cv::Mat mask{};                  // 8-bit
    std::optional<double> odom_mm{}; // finite; nullopt: unknown
    cv::Mat plant_class{};           // 8-bit grey, 0 soil, 1 crop, 2 weed
};

struct RecordingWriterOptions {
    RecordingColumns columns;
    // zlib level 0..9 for every PNG; -1 keeps OpenCV's own default (its
    // fastest level with a fixed SUB filter), which gives other bytes.
    int png_compression_level = -1;
};

class RecordingWriter {
public:
    // Creates `dir` and the image folders the columns need, and frames.csv
    // (truncated) with its header. False with the path and reason in `error`.
    bool open(const std::filesystem::path& dir, const RecordingWriterOptions& options, std::string& error);

    // Writes the frame's PNGs, then its row. False with the file and the
    // reason (errno's text where there is one) in `error`; frames.csv then
    // still ends on the previous frame's complete row.
    bool append(const FrameToWrite& frame, std::string& error);

    std::uint64_t frames_written() const { return frames_written_; }
    // The row the last successful append() wrote, as read_recording reads
    // it back: callers that refer to a frame by its rgb path (stems.csv)
    // take the name from here rather than spell the naming again.
    const RecordingFrame& last_written() const { return last_written_; }

private:
    // Encodes `image` as <dir>/<folder>/NNNNNN.png; `relative` gets the
    // name as frames.csv holds it.
    bool write_png(std::string_view folder, const cv::Mat& image, std::string& relative, std::string& error);

    std::filesystem::path dir_;
    RecordingColumns columns_;
    std::vector<int> png_params_;
    base::RecordFile csv_;
    std::vector<unsigned char> png_bytes_;   // reused from frame to frame
    std::string row_;                        // likewise
    std::uint64_t frames_written_ = 0;
    RecordingFrame last_written_;
};

}  // namespace stemd::io
