// Recording directories: the format stemd-synth writes, stemd-detect reads
// and the daemon replays. A folder with frames.csv:
//   t_ns,rgb,nir,mask
//   0,rgb/000000.png,nir/000000.png,mask/000000.png
// t_ns: capture time (CLOCK_MONOTONIC ns) as an integer; paths relative to
// the folder (absolute paths are taken as they are); nir and mask may be empty.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace stemd::io {

struct RecordingFrame {
    std::int64_t t_ns = 0;
    std::string rgb;   // as written in frames.csv
    std::string nir;
    std::string mask;
};

struct Recording {
    std::filesystem::path dir;
    std::vector<RecordingFrame> frames;

    std::filesystem::path resolve(const std::string& relative) const { return dir / relative; }
};

inline constexpr const char* kFramesCsvHeader = "t_ns,rgb,nir,mask";

bool is_recording_dir(const std::filesystem::path& path);
// Errors name the file and line: "<dir>/frames.csv:<line>: <reason>".
std::optional<Recording> read_recording(const std::filesystem::path& dir, std::string& error);

// Loads an image; on failure (missing, unreadable, corrupt) returns false
// and says why in `error` with the path. flags as cv::imread.
bool load_image(const std::filesystem::path& path, int imread_flags, cv::Mat& out, std::string& error);

}  // namespace stemd::io
