#include "stemd/io/recording.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <system_error>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/base/whole_file.hpp"
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

namespace {

std::uint32_t big_endian(const unsigned char* p, int bytes)
{
    std::uint32_t v = 0;
    for (int i = 0; i < bytes; ++i)
        v = v << 8 | p[i];
    return v;
}

std::int64_t little_endian(const unsigned char* p, int bytes)
{
    std::uint32_t v = 0;
    for (int i = bytes - 1; i >= 0; --i)
        v = v << 8 | p[i];
    // Sign-extend: BMP heights are signed (negative: stored top-down).
    const int shift = 32 - 8 * bytes;
    return static_cast<std::int32_t>(v << shift) >> shift;
}

std::optional<cv::Size> png_size(std::span<const unsigned char> b, std::string& why)
{
    // Signature (8), then the first chunk, IHDR: length (4), type (4), width, height.
    if (b.size() < 24 || std::string_view(reinterpret_cast<const char*>(b.data()) + 12, 4) != "IHDR") {
        why = "PNG without an IHDR header";
        return std::nullopt;
    }
    const std::uint32_t w = big_endian(b.data() + 16, 4), h = big_endian(b.data() + 20, 4);
    if (w == 0 || h == 0 || w > 0x7fffffff || h > 0x7fffffff) {
        why = "PNG header declares " + std::to_string(w) + "x" + std::to_string(h);
        return std::nullopt;
    }
    return cv::Size(static_cast<int>(w), static_cast<int>(h));
}

std::optional<cv::Size> jpeg_size(std::span<const unsigned char> b, std::string& why)
{
    // Marker segments up to the first start-of-frame (SOF0..SOF15, but not
    // DHT C4, JPG C8, DAC CC), whose payload holds precision, height, width.
    std::size_t i = 2;
    while (i + 4 <= b.size()) {
        if (b[i] != 0xFF)
            break;
        const unsigned char marker = b[i + 1];
        if (marker == 0xFF) {   // fill byte
            ++i;
            continue;
        }
        if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {   // no payload
            i += 2;
            continue;
        }
        const std::size_t length = big_endian(b.data() + i + 2, 2);
        if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC) {
            if (length < 7 || i + 9 > b.size())
                break;
            const int h = static_cast<int>(big_endian(b.data() + i + 5, 2));
            const int w = static_cast<int>(big_endian(b.data() + i + 7, 2));
            if (w == 0 || h == 0)
                break;
            return cv::Size(w, h);
        }
        if (marker == 0xDA || marker == 0xD9 || length < 2)
            break;   // scan data or the end before any frame header
        i += 2 + length;
    }
    why = "JPEG without a readable frame header";
    return std::nullopt;
}

// Whether a PNG's chunks run whole to its IEND chunk. libpng refuses a PNG
// cut off in its image data anyway, but only after decoding it, with a line
// of its own on stderr.
bool png_complete(std::span<const unsigned char> b)
{
    std::size_t i = 8;   // after the signature: chunks of length (4), type (4), data, CRC (4)
    while (i + 12 <= b.size()) {
        const std::size_t length = big_endian(b.data() + i, 4);
        if (std::string_view(reinterpret_cast<const char*>(b.data()) + i + 4, 4) == "IEND")
            return true;
        if (length > b.size() - i - 12)
            return false;
        i += 12 + length;
    }
    return false;
}

// Whether a JPEG's data runs to its end-of-image marker (EOI). libjpeg
// decodes a JPEG cut off inside its scan data without failing: it fills
// the missing rows with grey and only warns, so a cut-off file (an
// interrupted copy, a failing card) would pass for a whole frame. Marker
// segments are skipped by their length; inside a scan's entropy-coded data
// a 0xFF byte is followed by 0x00 (a stuffed byte) or a restart marker, so
// the first other marker ends the scan. Bytes after the EOI (a second
// picture, a vendor's trailer) are not looked at, as the decoder does not.
bool jpeg_complete(std::span<const unsigned char> b)
{
    std::size_t i = 2;   // after SOI
    while (i + 2 <= b.size()) {
        if (b[i] != 0xFF)
            return false;   // no marker where one belongs
        const unsigned char marker = b[i + 1];
        if (marker == 0xFF) {   // fill byte
            ++i;
            continue;
        }
        if (marker == 0xD9)
            return true;
        if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {   // no payload
            i += 2;
            continue;
        }
        if (i + 4 > b.size())
            return false;
        const std::size_t length = big_endian(b.data() + i + 2, 2);
        if (length < 2)
            return false;
        i += 2 + length;
        if (marker != 0xDA)
            continue;
        for (;;) {   // the scan's entropy-coded data, up to the next marker
            if (i >= b.size())
                return false;
            const auto* ff = static_cast<const unsigned char*>(std::memchr(b.data() + i, 0xFF, b.size() - i));
            if (ff == nullptr)
                return false;
            i = static_cast<std::size_t>(ff - b.data());
            if (i + 1 >= b.size())
                return false;
            const unsigned char next = b[i + 1];
            if (next == 0x00 || (next >= 0xD0 && next <= 0xD7))
                i += 2;
            else if (next == 0xFF)
                ++i;
            else
                break;
        }
    }
    return false;
}

std::optional<cv::Size> bmp_size(std::span<const unsigned char> b, std::string& why)
{
    // File header (14), then the DIB header: its size, then the dimensions
    // (16-bit in the old 12-byte core header, 32-bit in every later one).
    if (b.size() >= 26) {
        const std::int64_t dib = little_endian(b.data() + 14, 4);
        const bool core = dib == 12;
        const std::int64_t w = little_endian(b.data() + 18, core ? 2 : 4);
        const std::int64_t h = std::abs(little_endian(b.data() + (core ? 20 : 22), core ? 2 : 4));
        if (w > 0 && h > 0)
            return cv::Size(static_cast<int>(w), static_cast<int>(h));
    }
    why = "BMP without a readable header";
    return std::nullopt;
}

// A PNM header's decimal fields after the magic ("P1".."P6"): width,
// height and, but for the bitmaps (P1, P4), the maximum value, separated by
// whitespace and '#' comments. `end` is where the last one ends; false when
// one is missing or longer than ten digits.
bool pnm_fields(std::span<const unsigned char> b, std::span<long long> values, std::size_t& end)
{
    std::size_t i = 2;
    for (long long& v : values) {
        v = 0;
        while (i < b.size() && (std::isspace(b[i]) || b[i] == '#')) {
            if (b[i] == '#')
                while (i < b.size() && b[i] != '\n')
                    ++i;
            else
                ++i;
        }
        int digits = 0;
        for (; i < b.size() && std::isdigit(b[i]) && digits < 10; ++i, ++digits)
            v = v * 10 + (b[i] - '0');
        if (digits == 0 || (i < b.size() && std::isdigit(b[i])))
            return false;
    }
    end = i;
    return true;
}

std::optional<cv::Size> pnm_size(std::span<const unsigned char> b, std::string& why)
{
    long long values[2] = {0, 0};
    std::size_t end = 0;
    if (!pnm_fields(b, values, end)) {
        why = "PNM without a readable header";
        return std::nullopt;
    }
    if (values[0] <= 0 || values[1] <= 0 || values[0] > 0x7fffffff || values[1] > 0x7fffffff) {
        why = "PNM header declares " + std::to_string(values[0]) + "x" + std::to_string(values[1]);
        return std::nullopt;
    }
    return cv::Size(static_cast<int>(values[0]), static_cast<int>(values[1]));
}

// Whether a binary PNM (P4, P5, P6) holds all the pixels its header
// declares, which start after one whitespace byte past the header. A plain
// (ASCII) PNM's length says nothing: true.
bool pnm_complete(std::span<const unsigned char> b, cv::Size size)
{
    const unsigned char kind = b[1];
    if (kind < '4')
        return true;
    long long values[3] = {0, 0, 0};
    std::size_t end = 0;
    if (!pnm_fields(b, std::span(values).first(kind == '4' ? 2 : 3), end))
        return false;
    const auto w = static_cast<std::uint64_t>(size.width), h = static_cast<std::uint64_t>(size.height);
    const std::uint64_t sample_bytes = values[2] > 255 ? 2 : 1;
    const std::uint64_t pixels_bytes = kind == '4' ? (w + 7) / 8 * h : w * h * sample_bytes * (kind == '6' ? 3 : 1);
    return end + 1 <= b.size() && b.size() - end - 1 >= pixels_bytes;
}

// Whether a BMP is as long as its file header says (bfSize; 0 in some
// writers' files, which then cannot be checked).
bool bmp_complete(std::span<const unsigned char> b)
{
    const auto declared = static_cast<std::uint32_t>(little_endian(b.data() + 2, 4));
    return declared == 0 || b.size() >= declared;
}

}  // namespace

std::optional<cv::Size> declared_image_size(std::span<const unsigned char> b, std::string& why)
{
    static constexpr unsigned char kPng[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    if (b.size() >= sizeof kPng && std::equal(std::begin(kPng), std::end(kPng), b.begin()))
        return png_size(b, why);
    if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF)
        return jpeg_size(b, why);
    if (b.size() >= 2 && b[0] == 'B' && b[1] == 'M')
        return bmp_size(b, why);
    if (b.size() >= 2 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6')
        return pnm_size(b, why);
    why = "not a PNG, JPEG, BMP or PNM image";
    return std::nullopt;
}

HeaderCheck check_image_header(std::span<const unsigned char> bytes, cv::Size expected, std::string& why)
{
    const auto size = declared_image_size(bytes, why);
    if (!size)
        return HeaderCheck::unreadable;
    const bool wrong_size = !expected.empty() && *size != expected;
    if (wrong_size || size->width > kMaxImageSidePx || size->height > kMaxImageSidePx) {
        why = "declares " + std::to_string(size->width) + "x" + std::to_string(size->height) +
              (wrong_size ? ", the frames are " + std::to_string(expected.width) + "x" + std::to_string(expected.height)
                          : ", more than " + std::to_string(kMaxImageSidePx) + " px a side");
        return HeaderCheck::bad_size;
    }
    // declared_image_size() told the formats apart by their first bytes.
    if (bytes[0] == 0x89 && !png_complete(bytes)) {
        why = "PNG cut off: its chunks end before the IEND chunk";
        return HeaderCheck::unreadable;
    }
    if (bytes[0] == 0xFF && !jpeg_complete(bytes)) {
        why = "JPEG cut off: its data ends before the end-of-image marker";
        return HeaderCheck::unreadable;
    }
    if (bytes[0] == 'B' && !bmp_complete(bytes)) {
        why = "BMP cut off: shorter than its header says";
        return HeaderCheck::unreadable;
    }
    if (bytes[0] == 'P' && !pnm_complete(bytes, *size)) {
        why = "PNM cut off: fewer pixels than its header declares";
        return HeaderCheck::unreadable;
    }
    return HeaderCheck::ok;
}

bool read_whole_file(const std::filesystem::path& path, std::size_t max_bytes, std::vector<unsigned char>& bytes,
                     std::string& error)
{
    const base::WholeFileResult read = base::read_whole_file(path.c_str(), max_bytes, bytes);
    const auto errno_text = [&](const char* what) {
        return std::string(what) + ": " + std::strerror(read.error_number) + " (errno " +
               std::to_string(read.error_number) + ")";
    };
    switch (read.status) {
    case base::WholeFileStatus::ok: return true;
    case base::WholeFileStatus::cannot_open: error = errno_text("cannot open"); break;
    case base::WholeFileStatus::cannot_stat:
    case base::WholeFileStatus::read_error: error = errno_text("cannot read"); break;
    case base::WholeFileStatus::directory:
    case base::WholeFileStatus::not_regular: error = "not a regular file"; break;
    case base::WholeFileStatus::too_large:
        error = (read.size_is_lower_bound ? "at least " : "") + std::to_string(read.size_bytes) + " bytes, more than " +
                std::to_string(max_bytes);
        break;
    case base::WholeFileStatus::truncated:
        error = "cannot read: the file ended after " + std::to_string(read.read_bytes) + " of its " +
                std::to_string(read.size_bytes) + " bytes";
        break;
    }
    return false;
}

bool load_image(const std::filesystem::path& path, int imread_flags, cv::Mat& out, std::string& error)
{
    std::vector<unsigned char> bytes;
    if (!read_whole_file(path, kMaxImageFileBytes, bytes, error)) {
        error = path.string() + ": " + error;
        return false;
    }
    std::string why;
    switch (check_image_header(bytes, {}, why)) {
    case HeaderCheck::ok: break;
    case HeaderCheck::unreadable: error = path.string() + ": cannot decode: " + why; return false;
    case HeaderCheck::bad_size: error = path.string() + ": " + why + "; not decoded"; return false;
    }
    try {
        out = cv::imdecode(bytes, imread_flags);
    } catch (const cv::Exception& e) {
        error = path.string() + ": cannot decode: " + e.what();
        return false;
    } catch (const std::bad_alloc&) {
        error = path.string() + ": cannot decode: out of memory";
        return false;
    }
    if (out.empty()) {
        error = path.string() + ": cannot decode (corrupt or not an image)";
        return false;
    }
    return true;
}

}  // namespace stemd::io
