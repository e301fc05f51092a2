// RecordingWriter: what it writes is what read_recording reads, column by
// column and pixel by pixel, and its errors name the file.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/io/recording.hpp"
#include "stemd/io/recording_writer.hpp"

namespace fs = std::filesystem;
using namespace stemd::io;

namespace {

class RecordingWriterTest : public ::testing::Test {
protected:
    void SetUp() override
    {
        dir_ = fs::temp_directory_path() / ("stemd-recording-writer-" + std::to_string(std::random_device{}()));
    }
    void TearDown() override { fs::remove_all(dir_); }

    static cv::Mat random_image(int type, int seed, int max_value = 255)
    {
        cv::Mat image(24, 32, type);
        cv::RNG rng(static_cast<std::uint64_t>(seed));
        rng.fill(image, cv::RNG::UNIFORM, 0, max_value + 1);
        return image;
    }
    static bool same_pixels(const cv::Mat& a, const cv::Mat& b)
    {
        return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
    }
    cv::Mat load(const Recording& rec, const std::string& relative, int flags) const
    {
        return cv::imread(rec.resolve(relative).string(), flags);
    }
    std::string first_line() const
    {
        std::ifstream in(dir_ / "frames.csv");
        std::string line;
        std::getline(in, line);
        return line;
    }

    fs::path dir_;
    std::string error_;
};

}  // namespace

TEST_F(RecordingWriterTest, EveryColumnReadsBackFieldByField)
{
    const RecordingWriterOptions options{.columns = {.nir = true, .mask = true, .odom_mm = true, .plant_class = true}};
    RecordingWriter writer;
    ASSERT_TRUE(writer.open(dir_, options, error_)) << error_;
    std::vector<FrameToWrite> frames;
    std::vector<RecordingFrame> rows;   // last_written() after each frame
    for (int i = 0; i < 5; ++i) {
        FrameToWrite f;
        f.t_ns = 1'000'000'000 + i * 33'333'333LL;
        f.bgr = random_image(CV_8UC3, 4 * i);
        f.nir = random_image(CV_8UC1, 4 * i + 1);
        f.mask = random_image(CV_8UC1, 4 * i + 2);
        // Frame 2 has no odometer reading; values that need all 17 digits must survive.
        if (i != 2)
            f.odom_mm = 0.1 * i + 1.0 / 3.0;
        // Frame 3 has no class map.
        if (i != 3)
            f.plant_class = random_image(CV_8UC1, 4 * i + 3, 2);
        frames.push_back(f);
        ASSERT_TRUE(writer.append(f, error_)) << error_;
        rows.push_back(writer.last_written());
    }
    EXPECT_EQ(writer.frames_written(), frames.size());

    const auto rec = read_recording(dir_, error_);
    ASSERT_TRUE(rec) << error_;
    ASSERT_EQ(rec->frames.size(), frames.size());
    for (std::size_t i = 0; i < frames.size(); ++i) {
        SCOPED_TRACE("frame " + std::to_string(i));
        const RecordingFrame& got = rec->frames[i];
        EXPECT_EQ(got.t_ns, frames[i].t_ns);
        EXPECT_TRUE(same_pixels(load(*rec, got.rgb, cv::IMREAD_COLOR), frames[i].bgr));
        EXPECT_TRUE(same_pixels(load(*rec, got.nir, cv::IMREAD_GRAYSCALE), frames[i].nir));
        EXPECT_TRUE(same_pixels(load(*rec, got.mask, cv::IMREAD_GRAYSCALE), frames[i].mask));
        EXPECT_EQ(got.odom_mm, frames[i].odom_mm);
        EXPECT_EQ(rows[i].t_ns, got.t_ns);
        EXPECT_EQ(rows[i].rgb, got.rgb);
        EXPECT_EQ(rows[i].nir, got.nir);
        EXPECT_EQ(rows[i].mask, got.mask);
        EXPECT_EQ(rows[i].odom_mm, got.odom_mm);
        EXPECT_EQ(rows[i].plant_class, got.plant_class);
        if (frames[i].plant_class.empty())
            EXPECT_TRUE(got.plant_class.empty());
        else
            EXPECT_TRUE(same_pixels(load(*rec, got.plant_class, cv::IMREAD_GRAYSCALE), frames[i].plant_class));
    }
    // The names the tools have always written.
    EXPECT_EQ(rec->frames[1].rgb, "rgb/000001.png");
    EXPECT_EQ(rec->frames[1].nir, "nir/000001.png");
    EXPECT_EQ(rec->frames[1].mask, "mask/000001.png");
    EXPECT_EQ(rec->frames[1].plant_class, "class/000001.png");
}

TEST_F(RecordingWriterTest, EveryHeaderIsOneTheReaderAccepts)
{
    for (int bits = 0; bits < 16; ++bits) {
        const RecordingColumns columns{
            .nir = (bits & 1) != 0, .mask = (bits & 2) != 0, .odom_mm = (bits & 4) != 0, .plant_class = (bits & 8) != 0};
        SCOPED_TRACE("columns " + std::to_string(bits));
        fs::remove_all(dir_);
        RecordingWriter writer;
        ASSERT_TRUE(writer.open(dir_, {.columns = columns}, error_)) << error_;
        EXPECT_EQ(first_line(), frames_csv_header(columns));
        FrameToWrite f{.t_ns = 7, .bgr = random_image(CV_8UC3, bits)};
        if (columns.nir)
            f.nir = random_image(CV_8UC1, 1);
        if (columns.mask)
            f.mask = random_image(CV_8UC1, 2);
        if (columns.odom_mm)
            f.odom_mm = 12.5;
        if (columns.plant_class)
            f.plant_class = random_image(CV_8UC1, 3, 2);
        ASSERT_TRUE(writer.append(f, error_)) << error_;
        const auto rec = read_recording(dir_, error_);
        ASSERT_TRUE(rec) << error_;
        ASSERT_EQ(rec->frames.size(), 1u);
        EXPECT_EQ(rec->frames[0].nir.empty(), !columns.nir);
        EXPECT_EQ(rec->frames[0].mask.empty(), !columns.mask);
        EXPECT_EQ(rec->frames[0].odom_mm.has_value(), columns.odom_mm);
        EXPECT_EQ(rec->frames[0].plant_class.empty(), !columns.plant_class);
    }
}

TEST_F(RecordingWriterTest, AMaskOnlyFrameHasAnEmptyRgbField)
{
    RecordingWriter writer;
    ASSERT_TRUE(writer.open(dir_, {.columns = {.mask = true}}, error_)) << error_;
    ASSERT_TRUE(writer.append({.t_ns = 0, .mask = random_image(CV_8UC1, 1)}, error_)) << error_;
    const auto rec = read_recording(dir_, error_);
    ASSERT_TRUE(rec) << error_;
    ASSERT_EQ(rec->frames.size(), 1u);
    EXPECT_TRUE(rec->frames[0].rgb.empty());
    EXPECT_EQ(rec->frames[0].mask, "mask/000000.png");
}

TEST_F(RecordingWriterTest, RefusedFramesLeaveTheFileAsItWas)
{
    RecordingWriter writer;
    ASSERT_TRUE(writer.open(dir_, {}, error_)) << error_;
    ASSERT_TRUE(writer.append({.t_ns = 0, .bgr = random_image(CV_8UC3, 1)}, error_)) << error_;
    const std::string csv = (dir_ / "frames.csv").string();

    // A value for a column the recording does not have is not dropped silently.
    EXPECT_FALSE(writer.append({.t_ns = 1, .bgr = random_image(CV_8UC3, 2), .odom_mm = 5.0}, error_));
    EXPECT_NE(error_.find(csv), std::string::npos) << error_;
    EXPECT_FALSE(writer.append({.t_ns = 1, .bgr = random_image(CV_8UC3, 2), .nir = random_image(CV_8UC1, 3)}, error_));
    EXPECT_FALSE(writer.append({.t_ns = 1}, error_));
    EXPECT_NE(error_.find("rgb or a mask"), std::string::npos) << error_;

    const auto rec = read_recording(dir_, error_);
    ASSERT_TRUE(rec) << error_;
    EXPECT_EQ(rec->frames.size(), 1u);
    EXPECT_EQ(writer.frames_written(), 1u);
}

TEST_F(RecordingWriterTest, ANonFiniteOdometerIsRefused)
{
    RecordingWriter writer;
    ASSERT_TRUE(writer.open(dir_, {.columns = {.odom_mm = true}}, error_)) << error_;
    EXPECT_FALSE(writer.append({.t_ns = 0, .bgr = random_image(CV_8UC3, 1), .odom_mm = std::nan("")}, error_));
    EXPECT_NE(error_.find("odom_mm"), std::string::npos) << error_;
}

TEST_F(RecordingWriterTest, ErrorsNameTheFileAndTheReason)
{
    // A plain file where the directory should be.
    std::ofstream(dir_.string()) << "x";
    RecordingWriter writer;
    EXPECT_FALSE(writer.open(dir_, {}, error_));
    EXPECT_NE(error_.find((dir_ / "rgb").string()), std::string::npos) << error_;
    fs::remove(dir_);

    // frames.csv cannot be created: a directory is in its place.
    fs::create_directories(dir_ / "frames.csv");
    EXPECT_FALSE(writer.open(dir_, {}, error_));
    EXPECT_NE(error_.find((dir_ / "frames.csv").string() + ": cannot create: Is a directory"), std::string::npos)
        << error_;
    fs::remove_all(dir_);

    // A PNG cannot be created: a directory is in its place.
    ASSERT_TRUE(writer.open(dir_, {}, error_)) << error_;
    fs::create_directories(dir_ / "rgb" / "000000.png");
    EXPECT_FALSE(writer.append({.t_ns = 0, .bgr = random_image(CV_8UC3, 1)}, error_));
    EXPECT_NE(error_.find((dir_ / "rgb" / "000000.png").string() + ": cannot create: Is a directory"),
              std::string::npos)
        << error_;
}
