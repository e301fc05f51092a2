// One optional line file of the daemon (runtime/record_output.hpp), with and
// without the writer thread: whole lines after the header, every lost line
// makes close() false, a failure is logged once and later lines still go.
#include "stemd/runtime/record_output.hpp"

#include <cerrno>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "captured_log.hpp"
#include "temp_dir_test.hpp"

namespace {

using stemd::runtime::RecordOutput;
using stemd::runtime::RecordWriter;

std::string contents(const std::filesystem::path& path)
{
    std::ifstream in(path);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

std::size_t occurrences(const std::string& text, const std::string& what)
{
    std::size_t n = 0;
    for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size()))
        ++n;
    return n;
}

class RecordOutputTest : public stemd::test::TempDirTest {};

TEST_F(RecordOutputTest, WithoutAWriterTheHeaderAndEveryLineAreWrittenAtOnce)
{
    stemd::test::CapturedLog log;
    RecordOutput out("detections CSV", log.logger);
    ASSERT_TRUE(out.open(dir_ / "d.csv", "a,b\n"));
    EXPECT_EQ(contents(dir_ / "d.csv"), "a,b\n");
    EXPECT_TRUE(out.write("1,2\n"));
    EXPECT_EQ(contents(dir_ / "d.csv"), "a,b\n1,2\n") << "written before write() returned";
    EXPECT_TRUE(out.write("3,4\n"));
    EXPECT_TRUE(out.close());
    EXPECT_EQ(contents(dir_ / "d.csv"), "a,b\n1,2\n3,4\n");
    EXPECT_EQ(log.text(), "");
}

TEST_F(RecordOutputTest, AFileThatCannotBeCreatedIsNamedWithWhatItIsAndItsErrno)
{
    stemd::test::CapturedLog log;
    RecordOutput out("plant map", log.logger);
    const std::filesystem::path path = dir_ / "no-such-folder" / "map.jsonl";
    EXPECT_FALSE(out.open(path));
    EXPECT_FALSE(out.is_open());
    EXPECT_NE(log.text().find(path.string() + ": cannot create the plant map: No such file or directory (errno 2)"),
              std::string::npos)
        << log.text();
}

TEST_F(RecordOutputTest, AFailedWriteIsLoggedOnceAndLaterLinesAreStillTried)
{
    stemd::test::CapturedLog log;
    RecordOutput out("plant map", log.logger);
    ASSERT_TRUE(out.open("/dev/full"));   // every write: ENOSPC
    for (int i = 0; i < 3; ++i)
        EXPECT_FALSE(out.write("{}\n")) << "line " << i << " was lost";
    EXPECT_EQ(occurrences(log.text(), "/dev/full: plant map line lost: No space left on device (errno 28)"), 1u)
        << log.text();
    EXPECT_FALSE(out.close()) << "lines were lost";
}

TEST_F(RecordOutputTest, ALineThatCouldNotBeMadeIsLostButTheNextOneIsWritten)
{
    stemd::test::CapturedLog log;
    RecordOutput out("plant map", log.logger);
    ASSERT_TRUE(out.open(dir_ / "map.jsonl"));
    EXPECT_FALSE(out.lose(EOVERFLOW));
    EXPECT_TRUE(out.write("{\"id\":1}\n"));
    EXPECT_FALSE(out.close()) << "a line was lost";
    EXPECT_EQ(contents(dir_ / "map.jsonl"), "{\"id\":1}\n");
    EXPECT_NE(log.text().find("plant map line lost: Value too large for defined data type (errno 75)"),
              std::string::npos)
        << log.text();
}

TEST_F(RecordOutputTest, AttachedItsLinesGoThroughTheWriterAndCloseWaitsForTheLast)
{
    stemd::test::CapturedLog log;
    RecordWriter writer(64, log.logger);
    RecordOutput out("detections CSV", log.logger);
    ASSERT_TRUE(out.open(dir_ / "d.csv", "h\n"));
    out.attach(writer);
    writer.start();
    constexpr int kLines = 500;   // several times the ring: it wraps
    std::string expected = "h\n";
    for (int i = 0; i < kLines; ++i) {
        const std::string line = std::to_string(i) + "\n";
        ASSERT_TRUE(out.write(line)) << "line " << i;   // at most 32 queued between flushes: it fits
        expected += line;
        if (i % 32 == 31)
            writer.flush();
    }
    EXPECT_TRUE(out.close());
    EXPECT_EQ(contents(dir_ / "d.csv"), expected) << "close() returned before the writer's last line";
    writer.stop();
}

TEST_F(RecordOutputTest, AttachedALineTheWriterDroppedMakesCloseFalse)
{
    stemd::test::CapturedLog log;
    RecordWriter writer(2, log.logger);   // not started yet: the third line finds the ring full
    RecordOutput out("plant map", log.logger);
    ASSERT_TRUE(out.open(dir_ / "map.jsonl"));
    out.attach(writer);
    EXPECT_TRUE(out.write("a\n"));
    EXPECT_TRUE(out.write("b\n"));
    EXPECT_FALSE(out.write("c\n"));
    writer.start();
    EXPECT_FALSE(out.close());
    EXPECT_EQ(contents(dir_ / "map.jsonl"), "a\nb\n");
    writer.stop();
}

}  // namespace
