// frames.csv: the four fixed columns, the optional odom_mm and class
// columns, and errors naming file and line; and the whole-file read that
// image loading and replay use.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "stemd/io/recording.hpp"
#include "temp_dir_test.hpp"

namespace fs = std::filesystem;
using namespace stemd::io;

namespace {

class RecordingTest : public stemd::test::TempDirTest {
protected:

    std::optional<Recording> read(const std::string& csv)
    {
        std::ofstream(dir_ / "frames.csv") << csv;
        error_.clear();
        return read_recording(dir_, error_);
    }
    std::string where(int line) const { return (dir_ / "frames.csv").string() + ":" + std::to_string(line) + ": "; }
    std::string error_;
};

}  // namespace

TEST_F(RecordingTest, FourColumnFilesReadAsBefore)
{
    const auto rec = read("t_ns,rgb,nir,mask\n0,rgb/0.png,nir/0.png,mask/0.png\n5,rgb/1.png,,\n");
    ASSERT_TRUE(rec) << error_;
    ASSERT_EQ(rec->frames.size(), 2u);
    EXPECT_EQ(rec->frames[0].t_ns, 0);
    EXPECT_EQ(rec->frames[0].rgb, "rgb/0.png");
    EXPECT_EQ(rec->frames[0].nir, "nir/0.png");
    EXPECT_EQ(rec->frames[0].mask, "mask/0.png");
    EXPECT_EQ(rec->frames[1].t_ns, 5);
    EXPECT_TRUE(rec->frames[1].nir.empty());
    for (const RecordingFrame& f : rec->frames) {
        EXPECT_FALSE(f.odom_mm.has_value());
        EXPECT_TRUE(f.plant_class.empty());
    }
    EXPECT_EQ(rec->resolve("rgb/0.png"), dir_ / "rgb/0.png");
}

TEST_F(RecordingTest, OdometerAndClassColumns)
{
    const auto rec = read(
        "t_ns,rgb,nir,mask,odom_mm,class\n"
        "1000,rgb/0.png,,,0,class/0.png\n"
        "2000,rgb/1.png,,,46.2,\n"
        "3000,rgb/2.png,,,,class/2.png\n"
        "4000,rgb/3.png,,,1.5e3,class/3.png\n");
    ASSERT_TRUE(rec) << error_;
    ASSERT_EQ(rec->frames.size(), 4u);
    EXPECT_EQ(rec->frames[0].odom_mm, 0.0);
    EXPECT_EQ(rec->frames[0].plant_class, "class/0.png");
    EXPECT_EQ(rec->frames[1].odom_mm, 46.2);
    EXPECT_TRUE(rec->frames[1].plant_class.empty());
    EXPECT_FALSE(rec->frames[2].odom_mm.has_value());
    EXPECT_EQ(rec->frames[2].plant_class, "class/2.png");
    EXPECT_EQ(rec->frames[3].odom_mm, 1500.0);
}

TEST_F(RecordingTest, OptionalColumnsInAnyOrderAndAlone)
{
    auto rec = read("t_ns,rgb,nir,mask,class,odom_mm\n0,a.png,,,c.png,12.5\n");
    ASSERT_TRUE(rec) << error_;
    EXPECT_EQ(rec->frames[0].odom_mm, 12.5);
    EXPECT_EQ(rec->frames[0].plant_class, "c.png");

    rec = read("t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,7\n");
    ASSERT_TRUE(rec) << error_;
    EXPECT_EQ(rec->frames[0].odom_mm, 7.0);
    EXPECT_TRUE(rec->frames[0].plant_class.empty());

    rec = read("t_ns,rgb,nir,mask,class\n0,a.png,,,c.png\n");
    ASSERT_TRUE(rec) << error_;
    EXPECT_FALSE(rec->frames[0].odom_mm.has_value());
    EXPECT_EQ(rec->frames[0].plant_class, "c.png");
}

TEST_F(RecordingTest, UnknownOrRepeatedColumnIsAnError)
{
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,x\n0,a.png,,,1\n"));
    EXPECT_EQ(error_, where(1) + "unknown column 'x'");
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,odom_mm,speed\n0,a.png,,,1,2\n"));
    EXPECT_EQ(error_, where(1) + "unknown column 'speed'");
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,class,class\n0,a.png,,,c,c\n"));
    EXPECT_EQ(error_, where(1) + "column 'class' appears twice");
}

TEST_F(RecordingTest, FixedColumnsMustComeFirst)
{
    EXPECT_FALSE(read("t_ns,rgb,mask,nir\n0,a.png,,\n"));
    EXPECT_NE(error_.find(where(1)), std::string::npos) << error_;
    EXPECT_FALSE(read("odom_mm,t_ns,rgb,nir,mask\n0,0,a.png,,\n"));
    EXPECT_NE(error_.find(where(1)), std::string::npos) << error_;
    EXPECT_FALSE(read("t_ns,rgb,nir\n0,a.png,\n"));
    EXPECT_NE(error_.find(where(1)), std::string::npos) << error_;
}

TEST_F(RecordingTest, BadOdometerValuesNameTheLine)
{
    for (const char* bad : {"abc", "1.5mm", "nan", "inf", "-inf", " 3", "1e999"}) {
        SCOPED_TRACE(bad);
        EXPECT_FALSE(read(std::string("t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,1\n1,b.png,,,") + bad + "\n"));
        EXPECT_EQ(error_, where(3) + "odom_mm '" + bad + "' is not a finite number");
    }
}

TEST_F(RecordingTest, OtherRowErrors)
{
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,odom_mm\nx,a.png,,,1\n"));
    EXPECT_EQ(error_, where(2) + "t_ns 'x' is not an integer");
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,class\n0,,,,c.png\n"));
    EXPECT_EQ(error_, where(2) + "a frame needs an rgb or a mask path");
}

TEST_F(RecordingTest, AFramesCsvThatIsNoFileIsRefusedAtOnce)
{
    // A FIFO no one writes (a blocking read would hang the replay's start
    // until ctest's timeout), and a directory.
    const fs::path csv = dir_ / "frames.csv";
    ASSERT_EQ(::mkfifo(csv.c_str(), 0600), 0);
    EXPECT_FALSE(read_recording(dir_, error_));
    EXPECT_EQ(error_, csv.string() + ": not a regular file");
    fs::remove(csv);
    fs::create_directory(csv);
    EXPECT_FALSE(read_recording(dir_, error_));
    EXPECT_EQ(error_, csv.string() + ": not a regular file");
    fs::remove(csv);
    EXPECT_FALSE(read_recording(dir_, error_));
    EXPECT_EQ(error_, csv.string() + ": cannot open: No such file or directory (errno 2)");
    // Lines end in \n or \r\n, the last one may have neither, blank ones
    // are skipped, and errors name the file's own line.
    std::ofstream(csv, std::ios::binary) << "t_ns,rgb,nir,mask\r\n\n0,a.png,,\r\n  \n1000,b.png,,";
    const auto rec = read_recording(dir_, error_);
    ASSERT_TRUE(rec) << error_;
    ASSERT_EQ(rec->frames.size(), 2u);
    EXPECT_EQ(rec->frames[1].t_ns, 1000);
    EXPECT_EQ(rec->frames[1].rgb, "b.png");
    std::ofstream(csv, std::ios::binary) << "t_ns,rgb,nir,mask\r\n\n0,a.png,,\r\n  \nx,b.png,,";
    EXPECT_FALSE(read_recording(dir_, error_));
    EXPECT_EQ(error_, where(5) + "t_ns 'x' is not an integer");
}

TEST_F(RecordingTest, TimeMustIncreaseFromZeroWithBoundedGaps)
{
    EXPECT_FALSE(read("t_ns,rgb,nir,mask\n-1,a.png,,\n"));
    EXPECT_EQ(error_, where(2) + "t_ns -1 is negative (a capture time is CLOCK_MONOTONIC, never below 0)");
    EXPECT_FALSE(read("t_ns,rgb,nir,mask\n5,a.png,,\n5,b.png,,\n"));
    EXPECT_EQ(error_, where(3) + "t_ns 5 repeats line 2's 5 (t_ns must increase from frame to frame)");
    EXPECT_FALSE(read("t_ns,rgb,nir,mask\n5,a.png,,\n\n4,b.png,,\n"));
    EXPECT_EQ(error_, where(4) + "t_ns 4 is before line 2's 5 (t_ns must increase from frame to frame)");
    // 1e15 ns: eleven and a half days without a frame.
    EXPECT_FALSE(read("t_ns,rgb,nir,mask\n0,a.png,,\n1000000000000000,b.png,,\n"));
    EXPECT_EQ(error_, where(3) + "t_ns 1000000000000000 is 1000000 s after line 2's (at most 60 s between frames)");
    // Near the limits of int64: a step across the whole range is refused...
    EXPECT_FALSE(read("t_ns,rgb,nir,mask\n-9223372036854775808,a.png,,\n9223372036854775807,b.png,,\n"));
    EXPECT_EQ(error_.rfind(where(2), 0), 0U) << error_;
    EXPECT_FALSE(read("t_ns,rgb,nir,mask\n0,a.png,,\n9223372036854775807,b.png,,\n"));
    EXPECT_EQ(error_.rfind(where(3), 0), 0U) << error_;
    // ...a recording that merely starts late is fine.
    const auto rec = read("t_ns,rgb,nir,mask\n9223372036754775807,a.png,,\n9223372036854775807,b.png,,\n");
    ASSERT_TRUE(rec) << error_;
    EXPECT_EQ(rec->frames[1].t_ns - rec->frames[0].t_ns, 100'000'000);
    EXPECT_TRUE(read("t_ns,rgb,nir,mask\n0,a.png,,\n60000000000,b.png,,\n")) << error_;
}

TEST_F(RecordingTest, OdometerNeverDecreasesAndStaysInRange)
{
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,10\n1,b.png,,,\n2,c.png,,,9.5\n"));
    EXPECT_EQ(error_, where(4) + "odom_mm 9.5 is less than line 2's (the odometer never decreases)");
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,1e300\n"));
    EXPECT_EQ(error_, where(2) + "odom_mm 1e300 is beyond +-1e9 mm (1000 km)");
    EXPECT_FALSE(read("t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,-2e9\n"));
    EXPECT_EQ(error_, where(2) + "odom_mm -2e9 is beyond +-1e9 mm (1000 km)");
    // Standing still (equal readings) and a negative start are readings.
    EXPECT_TRUE(read("t_ns,rgb,nir,mask,odom_mm\n0,a.png,,,-5\n1,b.png,,,-5\n2,c.png,,,1e9\n")) << error_;
}

TEST(RecordingOdometer, ParsesFiniteReals)
{
    double v = -1;
    EXPECT_TRUE(parse_odom_mm("0", v));
    EXPECT_EQ(v, 0.0);
    EXPECT_TRUE(parse_odom_mm("3426.06", v));
    EXPECT_EQ(v, 3426.06);
    EXPECT_TRUE(parse_odom_mm("-2e1", v));
    EXPECT_EQ(v, -20.0);
    v = 5;
    EXPECT_FALSE(parse_odom_mm("", v));
    EXPECT_FALSE(parse_odom_mm("1,5", v));
    EXPECT_FALSE(parse_odom_mm("NaN", v));
    EXPECT_EQ(v, 5.0);
}

namespace {

using ReadWholeFileTest = stemd::test::TempDirTest;

}  // namespace

TEST_F(ReadWholeFileTest, ReadsEveryByteIntoAReusedBuffer)
{
    // A file larger than one read of a pipe or a page, of random bytes
    // (zeros included), read into a buffer that held more before.
    std::string content(3 * 1024 * 1024 + 17, '\0');
    std::mt19937 rng(7);
    for (char& c : content)
        c = static_cast<char>(rng() & 0xFF);
    const fs::path path = write(content, "frame.png");
    std::vector<unsigned char> bytes(5 * 1024 * 1024, 0xAB);
    std::string error;
    ASSERT_TRUE(read_whole_file(path, kMaxImageFileBytes, bytes, error)) << error;
    ASSERT_EQ(bytes.size(), content.size());
    EXPECT_TRUE(std::equal(bytes.begin(), bytes.end(), content.begin(),
                           [](unsigned char a, char b) { return a == static_cast<unsigned char>(b); }));
    EXPECT_TRUE(error.empty());
}

TEST_F(ReadWholeFileTest, AnEmptyFileGivesNoBytes)
{
    std::vector<unsigned char> bytes(10, 1);
    std::string error;
    EXPECT_TRUE(read_whole_file(write("", "empty.png"), kMaxImageFileBytes, bytes, error)) << error;
    EXPECT_TRUE(bytes.empty());
}

TEST_F(ReadWholeFileTest, SaysWhyAMissingFileADirectoryOrAFifoIsNotRead)
{
    std::vector<unsigned char> bytes;
    std::string error;
    EXPECT_FALSE(read_whole_file(dir_ / "missing.png", kMaxImageFileBytes, bytes, error));
    EXPECT_EQ(error, "cannot open: No such file or directory (errno 2)");
    EXPECT_FALSE(read_whole_file(dir_, kMaxImageFileBytes, bytes, error));
    EXPECT_EQ(error, "not a regular file");
    // No writer ever opens the FIFO: a blocking open or read would hang
    // here (and fail the test by ctest's timeout).
    const fs::path fifo = dir_ / "fifo.png";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    EXPECT_FALSE(read_whole_file(fifo, kMaxImageFileBytes, bytes, error));
    EXPECT_EQ(error, "not a regular file");
}

TEST_F(ReadWholeFileTest, RefusesAFileOverTheLimitBeforeAllocating)
{
    // A sparse file far larger than the limit: refused from its size alone,
    // and the buffer keeps what it held.
    const fs::path path = write("", "huge.png");
    fs::resize_file(path, kMaxImageFileBytes + 1);
    std::vector<unsigned char> bytes(3, 7);
    std::string error;
    EXPECT_FALSE(read_whole_file(path, kMaxImageFileBytes, bytes, error));
    EXPECT_EQ(error, std::to_string(kMaxImageFileBytes + 1) + " bytes, more than " + std::to_string(kMaxImageFileBytes));
    EXPECT_EQ(bytes, std::vector<unsigned char>(3, 7));
    // At the limit, read (a small limit, to keep the test small).
    const fs::path small = write(std::string(100, 'x'), "small.png");
    EXPECT_TRUE(read_whole_file(small, 100, bytes, error)) << error;
    EXPECT_EQ(bytes.size(), 100u);
    EXPECT_FALSE(read_whole_file(small, 99, bytes, error));
    EXPECT_EQ(error, "100 bytes, more than 99");
}

TEST_F(ReadWholeFileTest, AFileThatReportsNoSizeIsReadToItsEndWithinTheLimit)
{
    // The kernel's own files report a size of 0 and hold more: read on to
    // the end, as a file that grew after its size was taken would be.
    std::vector<unsigned char> bytes;
    std::string error;
    ASSERT_EQ(fs::file_size("/proc/self/status"), 0u) << "this kernel reports a size for /proc files";
    ASSERT_TRUE(read_whole_file("/proc/self/status", kMaxImageFileBytes, bytes, error)) << error;
    const std::string text(bytes.begin(), bytes.end());
    EXPECT_EQ(text.rfind("Name:", 0), 0u) << text.substr(0, 40);
    EXPECT_NE(text.find("\nPid:"), std::string::npos);
    // The limit holds for what is read beyond the reported size too.
    EXPECT_FALSE(read_whole_file("/proc/self/status", 10, bytes, error));
    EXPECT_EQ(error.rfind("at least ", 0), 0u) << error;
    EXPECT_NE(error.find(" bytes, more than 10"), std::string::npos) << error;
}
