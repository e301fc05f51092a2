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
//
// Time and odometer rules (checked by read_recording, so every reader
// refuses the same files):
//   - t_ns is at least 0 and strictly increases from row to row, by at most
//     kMaxFrameGapNs: replay paces by t_ns, and a duplicate, a step back or
//     a huge gap would deliver frames out of order or stall it;
//   - odom_mm never decreases (the odometer counts distance driven) and
//     stays within +-kMaxOdomMm.
// These are refused at load rather than counted while running: one bad
// value makes the whole run's pacing or every field position wrong, and a
// field engineer would rather fix the file than read a total line of
// garbage targets.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
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

// A frame's t_ns follows the previous one's by at most this (60 s): no
// camera pauses that long within one recording, and replay would sit idle
// for it.
inline constexpr std::int64_t kMaxFrameGapNs = 60'000'000'000;
// |odom_mm| at most this (1000 km): more is no odometer reading, and field
// positions computed from it would be meaningless.
inline constexpr double kMaxOdomMm = 1e9;

// An odom_mm field: a finite real as std::from_chars reads it (no spaces).
bool parse_odom_mm(std::string_view text, double& out);

bool is_recording_dir(const std::filesystem::path& path);
// The one reader of frames.csv: the tools and the replay source use it.
// Errors name the file and line: "<dir>/frames.csv:<line>: <reason>"
// (a bad header, an unknown or repeated column, a bad t_ns or odom_mm, or
// one that breaks the time and odometer rules above).
std::optional<Recording> read_recording(const std::filesystem::path& dir, std::string& error);

// The largest image side any reader decodes: the largest frame the
// daemon's slots can be configured for (source.width_px, height_px).
inline constexpr int kMaxImageSidePx = 8192;

// The size an image file declares in its header (PNG IHDR, JPEG SOFn, BMP,
// PNM), read without decoding. nullopt with the reason when the bytes are
// none of these formats, or the header is cut short or malformed: the
// readers decode nothing whose size they cannot check first.
std::optional<cv::Size> declared_image_size(std::span<const unsigned char> bytes, std::string& why);

enum class HeaderCheck : std::uint8_t { ok, unreadable, bad_size };
// Checks an encoded image before it is decoded: its declared size must be
// `expected` (when not empty), and no side may exceed kMaxImageSidePx, so a
// small file declaring a huge image is refused before it allocates
// (bad_size). A PNG must run whole to its IEND chunk, a JPEG to its
// end-of-image marker, a BMP or binary PNM to the length its header gives
// (else unreadable): libjpeg would decode a cut-off JPEG without failing,
// its missing rows grey, and the other decoders fail only after printing
// their own line on stderr. `why` says what is wrong (without the path).
HeaderCheck check_image_header(std::span<const unsigned char> bytes, cv::Size expected, std::string& why);

// The largest image file any reader reads: kMaxImageSidePx a side at eight
// bytes a pixel (16-bit RGBA, uncompressed), and 64 MiB of metadata.
inline constexpr std::size_t kMaxImageFileBytes =
    std::size_t{8} * kMaxImageSidePx * kMaxImageSidePx + (std::size_t{64} << 20);

// Reads the whole regular file at `path` into `bytes` (resized to its
// length; reused capacity is not given back), as base::read_whole_file. On
// failure returns false and says why in `error`, without the path: "cannot
// open: <reason> (errno N)", "not a regular file" (a FIFO is opened
// non-blocking and refused, never waited on), "N bytes, more than
// max_bytes" (refused from its size before anything is allocated; "at
// least N" when it grew past its size while read), or "cannot read: ...".
bool read_whole_file(const std::filesystem::path& path, std::size_t max_bytes, std::vector<unsigned char>& bytes,
                     std::string& error);

// Loads an image; on failure (missing, unreadable, corrupt, a header
// declaring an image larger than kMaxImageSidePx) returns false and says
// why in `error` with the path. flags as cv::imread.
bool load_image(const std::filesystem::path& path, int imread_flags, cv::Mat& out, std::string& error);

}  // namespace stemd::io
