// Recording directories: the format stemd-synth writes, stemd-detect reads
// and the daemon replays. A folder with frames.csv:
//   t_ns,rgb,nir,mask
//   0,rgb/000000.png,nir/000000.png,mask/000000.png
// t_ns: capture time (CLOCK_MONOTONIC ns) as an integer; paths relative to
// the folder (absolute paths are taken as they are); nir and mask may be
// empty; a frame needs an rgb or a mask path.
//
// After the four fixed columns, two optional ones, in any order, recognised
// by the header (any other column name is an error):
//   odom_mm  the odometer at capture (mm, a finite real); empty = unknown
//   class    a per-pixel class PNG (8-bit grey: 0 soil, 1 crop, 2 weed, as
//            PlantClass), the same size as rgb; empty = none
// e.g. stemd-synth --strip writes
//   t_ns,rgb,nir,mask,odom_mm,class
//   1000000000,rgb/000000.png,nir/000000.png,mask/000000.png,0,class/000000.png
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace stemd::io {

struct RecordingFrame {
    std::int64_t t_ns = 0;
    std::string rgb;   // as written in frames.csv
    std::string nir;
    std::string mask;
    std::optional<double> odom_mm;   // odom_mm column; nullopt when absent or empty
    std::string plant_class;          // class column; empty when absent or empty
};

struct Recording {
    std::filesystem::path dir;
    std::vector<RecordingFrame> frames;

    std::filesystem::path resolve(const std::string& relative) const { return dir / relative; }
};

// The four fixed columns; kFramesCsvOdomColumn / kFramesCsvClassColumn may follow.
inline constexpr const char* kFramesCsvHeader = "t_ns,rgb,nir,mask";
inline constexpr const char* kFramesCsvOdomColumn = "odom_mm";
inline constexpr const char* kFramesCsvClassColumn = "class";

// An odom_mm field: a finite real as std::from_chars reads it (no spaces).
bool parse_odom_mm(std::string_view text, double& out);

bool is_recording_dir(const std::filesystem::path& path);
// Errors name the file and line: "<dir>/frames.csv:<line>: <reason>"
// (a bad header, an unknown or repeated column, a bad t_ns or odom_mm).
std::optional<Recording> read_recording(const std::filesystem::path& dir, std::string& error);

// Loads an image; on failure (missing, unreadable, corrupt) returns false
// and says why in `error` with the path. flags as cv::imread.
bool load_image(const std::filesystem::path& path, int imread_flags, cv::Mat& out, std::string& error);

}  // namespace stemd::io
