// Image headers are read before decoding: the declared size of PNG, JPEG,
// BMP and PNM files, and a small file declaring a huge image refused
// without being decoded.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

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
    const fs::path path = fs::temp_directory_path() / ("stemd-header-" + std::to_string(std::random_device{}()) + ".png");
    const auto png = png_declaring(30000, 30000);
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(png.data()),
                                                static_cast<std::streamsize>(png.size()));
    cv::Mat out;
    std::string error;
    EXPECT_FALSE(load_image(path, cv::IMREAD_COLOR, out, error));
    EXPECT_EQ(error, path.string() + ": declares 30000x30000, more than 8192 px a side; not decoded");
    EXPECT_TRUE(out.empty());
    fs::remove(path);
}
