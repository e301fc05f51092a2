// Image headers are read before decoding: the declared size of PNG, JPEG,
// BMP and PNM files, and a small file declaring a huge image refused
// without being decoded.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/imgcodecs.hpp>

#include "forged_png.hpp"
#include "stemd/io/recording.hpp"

namespace fs = std::filesystem;
using namespace stemd::io;
using stemd::test::png_declaring;

namespace {

std::vector<unsigned char> encode(const std::string& ext, cv::Size size, int type = CV_8UC3)
{
    std::vector<unsigned char> bytes;
    EXPECT_TRUE(cv::imencode(ext, cv::Mat(size, type, cv::Scalar::all(90)), bytes));
    return bytes;
}

// A textured image: its JPEG's scan data holds many 0xFF bytes (stuffed
// with 0x00), as a field frame's does.
cv::Mat noise(cv::Size size)
{
    cv::Mat image(size, CV_8UC3);
    cv::RNG rng(7);
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    return image;
}

std::vector<unsigned char> encode_image(const std::string& ext, const cv::Mat& image,
                                        const std::vector<int>& params = {})
{
    std::vector<unsigned char> bytes;
    EXPECT_TRUE(cv::imencode(ext, image, bytes, params));
    return bytes;
}

// Where a JPEG's first scan starts (after the SOS segment), found by its
// marker segments: a cut after it is a cut in the image data.
std::size_t jpeg_scan_start(const std::vector<unsigned char>& b)
{
    std::size_t i = 2;
    while (i + 4 <= b.size() && !(b[i] == 0xFF && b[i + 1] == 0xDA))
        i += 2 + (static_cast<std::size_t>(b[i + 2]) << 8 | b[i + 3]);
    return i + 2 + (static_cast<std::size_t>(b[i + 2]) << 8 | b[i + 3]);
}

// load_image()'s error for `bytes` stored in a file, the file's path
// written as PATH; "" if it loaded, or returned an image with its error.
std::string load_error(std::span<const unsigned char> bytes)
{
    const fs::path path = fs::temp_directory_path() / ("stemd-header-" + std::to_string(std::random_device{}()));
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    cv::Mat out;
    std::string error;
    const bool loaded = load_image(path, cv::IMREAD_COLOR, out, error);
    fs::remove(path);
    if (loaded || !out.empty())
        return "";
    if (error.rfind(path.string(), 0) == 0)
        error.replace(0, path.string().size(), "PATH");
    return error;
}

}  // namespace

TEST(ImageHeader, DeclaredSizeOfEveryFormatTheReadersTake)
{
    const cv::Size size(37, 21);
    for (const char* ext : {".png", ".jpg", ".bmp", ".ppm", ".pgm"}) {
        SCOPED_TRACE(ext);
        std::string why;
        const auto bytes = encode(ext, size, std::string(ext) == ".pgm" ? CV_8UC1 : CV_8UC3);
        const auto declared = declared_image_size(bytes, why);
        ASSERT_TRUE(declared) << why;
        EXPECT_EQ(*declared, size);
        EXPECT_EQ(check_image_header(bytes, size, why), HeaderCheck::ok) << why;
        EXPECT_EQ(check_image_header(bytes, {}, why), HeaderCheck::ok) << why;
        EXPECT_EQ(check_image_header(bytes, {38, 21}, why), HeaderCheck::bad_size);
        EXPECT_EQ(why, "declares 37x21, the frames are 38x21");
    }
}

TEST(ImageHeader, PnmCommentsAndTruncatedOrUnknownFiles)
{
    std::string why;
    const std::string pgm = "P5\n# made by hand\n12 # width\n7\n255\n";
    const auto declared =
        declared_image_size({reinterpret_cast<const unsigned char*>(pgm.data()), pgm.size()}, why);
    ASSERT_TRUE(declared) << why;
    EXPECT_EQ(*declared, cv::Size(12, 7));

    const auto png = encode(".png", {8, 8});
    EXPECT_FALSE(declared_image_size(std::span(png).first(20), why));
    EXPECT_EQ(why, "PNG without an IHDR header");
    const auto jpg = encode(".jpg", {8, 8});
    EXPECT_FALSE(declared_image_size(std::span(jpg).first(4), why));
    EXPECT_EQ(why, "JPEG without a readable frame header");
    const std::string text = "not a png";
    EXPECT_EQ(check_image_header({reinterpret_cast<const unsigned char*>(text.data()), text.size()}, {}, why),
              HeaderCheck::unreadable);
    EXPECT_EQ(why, "not a PNG, JPEG, BMP or PNM image");
    EXPECT_EQ(check_image_header({}, {}, why), HeaderCheck::unreadable);
}

TEST(ImageHeader, HugeDeclaredSizeIsRefusedBeforeDecoding)
{
    std::string why;
    const auto png = png_declaring(30000, 30000);
    EXPECT_EQ(check_image_header(png, {}, why), HeaderCheck::bad_size);
    EXPECT_EQ(why, "declares 30000x30000, more than 8192 px a side");
    EXPECT_EQ(check_image_header(png, {1296, 966}, why), HeaderCheck::bad_size);
    EXPECT_EQ(why, "declares 30000x30000, the frames are 1296x966");
    EXPECT_EQ(check_image_header(png_declaring(8192, 8192), {}, why), HeaderCheck::ok) << why;
    EXPECT_EQ(check_image_header(png_declaring(0x80000000u, 1), {}, why), HeaderCheck::unreadable);
}

TEST(ImageHeader, LoadImageRefusesAHugeDeclaredSize)
{
    EXPECT_EQ(load_error(png_declaring(30000, 30000)),
              "PATH: declares 30000x30000, more than 8192 px a side; not decoded");
}

TEST(ImageHeader, AJpegCutOffInItsScanDataIsRefusedThoughTheDecoderWouldTakeIt)
{
    const auto jpg = encode_image(".jpg", noise({96, 64}));
    const std::size_t scan = jpeg_scan_start(jpg);
    ASSERT_LT(scan, jpg.size() - 2);
    std::string why;
    ASSERT_EQ(check_image_header(jpg, {96, 64}, why), HeaderCheck::ok) << why;
    // Why the check is needed: libjpeg decodes the half file, its missing
    // rows grey, and reports no error.
    const std::vector<unsigned char> half(jpg.begin(), jpg.begin() + static_cast<std::ptrdiff_t>(jpg.size() / 2));
    EXPECT_FALSE(cv::imdecode(half, cv::IMREAD_COLOR).empty());
    // Every cut from the scan's first byte to just before the EOI marker.
    for (std::size_t cut = scan; cut < jpg.size(); ++cut) {
        const std::span<const unsigned char> cut_off(jpg.data(), cut);
        ASSERT_EQ(check_image_header(cut_off, {96, 64}, why), HeaderCheck::unreadable) << "cut at " << cut;
        ASSERT_EQ(why, "JPEG cut off: its data ends before the end-of-image marker");
    }
}

TEST(ImageHeader, WholeJpegsWithRestartMarkersProgressiveScansOrATrailerAreTaken)
{
    const cv::Mat image = noise({96, 64});
    std::string why;
    const auto restarts = encode_image(".jpg", image, {cv::IMWRITE_JPEG_RST_INTERVAL, 1});
    EXPECT_EQ(check_image_header(restarts, {}, why), HeaderCheck::ok) << why;
    const auto progressive = encode_image(".jpg", image, {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
    EXPECT_EQ(check_image_header(progressive, {}, why), HeaderCheck::ok) << why;
    // A progressive JPEG cut between two of its scans.
    const std::size_t second_scan = [&] {
        // The first marker after the first scan's data (not a stuffed 0xFF
        // 0x00, not a restart marker).
        const auto& b = progressive;
        std::size_t i = jpeg_scan_start(b);
        while (i + 1 < b.size() && !(b[i] == 0xFF && b[i + 1] != 0x00 && (b[i + 1] < 0xD0 || b[i + 1] > 0xD7)))
            ++i;
        return i;
    }();
    ASSERT_LT(second_scan + 2, progressive.size()) << "one scan only";
    EXPECT_EQ(check_image_header(std::span(progressive).first(second_scan), {}, why), HeaderCheck::unreadable);
    // Bytes after the end-of-image marker (a vendor's trailer) are not read.
    auto trailer = encode_image(".jpg", image);
    for (const char c : std::string("SEFT trailer"))
        trailer.push_back(static_cast<unsigned char>(c));
    EXPECT_EQ(check_image_header(trailer, {}, why), HeaderCheck::ok) << why;
}

TEST(ImageHeader, AnEndMarkerInsideAMetadataSegmentDoesNotMakeACutJpegWhole)
{
    // An APP1 segment (where EXIF keeps a thumbnail, whole JPEG with its own
    // EOI) right after SOI: its bytes are skipped by the segment's length.
    auto jpg = encode_image(".jpg", noise({96, 64}));
    const std::vector<unsigned char> app1 = {0xFF, 0xE1, 0x00, 0x08, 0xFF, 0xD8, 0xFF, 0xD9, 0x00, 0x00};
    jpg.insert(jpg.begin() + 2, app1.begin(), app1.end());
    std::string why;
    ASSERT_EQ(check_image_header(jpg, {96, 64}, why), HeaderCheck::ok) << why;
    EXPECT_EQ(check_image_header(std::span(jpg).first(jpg.size() - 100), {96, 64}, why), HeaderCheck::unreadable);
}

TEST(ImageHeader, APngCutOffAnywhereAfterItsHeaderIsRefusedBeforeDecoding)
{
    const auto png = encode_image(".png", noise({96, 64}));
    std::string why;
    ASSERT_EQ(check_image_header(png, {96, 64}, why), HeaderCheck::ok) << why;
    for (std::size_t cut = 33; cut < png.size(); ++cut) {   // after the signature and IHDR (8 + 25 bytes)
        ASSERT_EQ(check_image_header(std::span(png).first(cut), {96, 64}, why), HeaderCheck::unreadable)
            << "cut at " << cut;
        ASSERT_EQ(why, "PNG cut off: its chunks end before the IEND chunk");
    }
}

TEST(ImageHeader, LoadImageRefusesACutOffJpeg)
{
    const auto jpg = encode_image(".jpg", noise({96, 64}));
    EXPECT_EQ(load_error(std::span(jpg).first(jpg.size() * 3 / 4)),
              "PATH: cannot decode: JPEG cut off: its data ends before the end-of-image marker");
}

TEST(ImageHeader, ABmpOrBinaryPnmCutOffAfterItsHeaderIsRefusedBeforeDecoding)
{
    const cv::Mat colour = noise({37, 21});
    cv::Mat grey;
    cv::extractChannel(colour, grey, 1);
    const struct {
        const char* ext;
        const cv::Mat& image;
        std::size_t header_bytes;
        const char* why;
    } cases[] = {{".bmp", colour, 54, "BMP cut off: shorter than its header says"},
                 {".ppm", colour, 15, "PNM cut off: fewer pixels than its header declares"},
                 {".pgm", grey, 15, "PNM cut off: fewer pixels than its header declares"}};
    for (const auto& c : cases) {
        SCOPED_TRACE(c.ext);
        const auto bytes = encode_image(c.ext, c.image);
        std::string why;
        ASSERT_EQ(check_image_header(bytes, {37, 21}, why), HeaderCheck::ok) << why;
        for (std::size_t cut = c.header_bytes; cut < bytes.size(); ++cut) {
            ASSERT_EQ(check_image_header(std::span(bytes).first(cut), {37, 21}, why), HeaderCheck::unreadable)
                << "cut at " << cut << " of " << bytes.size();
            ASSERT_EQ(why, c.why);
        }
    }
    // 16-bit samples take two bytes each.
    const std::string pgm16 = "P5 2 1 65535\n" + std::string(4, '\x7f');
    const std::span<const unsigned char> whole(reinterpret_cast<const unsigned char*>(pgm16.data()), pgm16.size());
    std::string why;
    EXPECT_EQ(check_image_header(whole, {}, why), HeaderCheck::ok) << why;
    EXPECT_EQ(check_image_header(whole.first(whole.size() - 1), {}, why), HeaderCheck::unreadable);
}
