// The writer thread of the optional outputs (runtime/record_writer.hpp):
// lines reach their own file in order, a stalled file holds up only the
// writer, and every lost line is counted.
#include "stemd/runtime/record_writer.hpp"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "captured_log.hpp"
#include "temp_dir_test.hpp"

namespace {

using stemd::base::RecordFile;
using stemd::runtime::RecordWriter;

std::vector<std::string> read_lines(const std::filesystem::path& path)
{
    std::ifstream in(path);
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);)
        lines.push_back(line);
    return lines;
}

std::string numbered(const char* prefix, int i) { return std::string(prefix) + std::to_string(i) + "\n"; }

class RecordWriterTest : public stemd::test::TempDirTest {};

// A pipe nobody reads yet: it takes its capacity (64 KiB), then write(2)
// blocks, as on a stalled disk. `file` writes into it, `read_fd` reads it.
struct UnreadPipe {
    RecordFile file;
    int read_fd = -1;
    int capacity_bytes = 0;
    UnreadPipe()
    {
        int fds[2];
        if (::pipe2(fds, O_CLOEXEC) != 0)
            return;
        capacity_bytes = ::fcntl(fds[1], F_GETPIPE_SZ);
        if (file.open_duplicate(fds[1]) == 0)
            read_fd = fds[0];
        else
            ::close(fds[0]);
        ::close(fds[1]);
    }
    ~UnreadPipe()
    {
        if (read_fd >= 0)
            ::close(read_fd);
    }
    // Reads until `bytes` came, nothing came for `quiet_ms`, or the writing
    // side is closed.
    std::string read_within(std::size_t bytes, int quiet_ms) const
    {
        std::string received;
        char buffer[4096];
        while (received.size() < bytes) {
            pollfd p{.fd = read_fd, .events = POLLIN, .revents = 0};
            if (::poll(&p, 1, quiet_ms) != 1)
                break;
            const ssize_t n = ::read(read_fd, buffer, std::min(sizeof buffer, bytes - received.size()));
            if (n <= 0)
                break;
            received.append(buffer, static_cast<std::size_t>(n));
        }
        return received;
    }
    // Reads until `bytes` came or the writing side is closed.
    std::string read(std::size_t bytes) const
    {
        std::string received;
        char buffer[4096];
        while (received.size() < bytes) {
            const ssize_t n = ::read(read_fd, buffer, sizeof buffer);
            if (n <= 0)
                break;
            received.append(buffer, static_cast<std::size_t>(n));
        }
        return received;
    }
};

TEST_F(RecordWriterTest, LinesReachTheirOwnFileInOrder)
{
    RecordFile a, b;
    ASSERT_EQ(a.open((dir_ / "a.csv").c_str()), 0);
    ASSERT_EQ(b.open((dir_ / "b.jsonl").c_str()), 0);
    stemd::test::CapturedLog log;
    RecordWriter writer(64, log.logger);
    const std::size_t ia = writer.add(a, "a.csv");
    const std::size_t ib = writer.add(b, "b.jsonl");
    writer.start();
    // Many times the ring's 64 cells, 32 lines between flushes: the ring
    // wraps while the writer drains it.
    constexpr int kLines = 1000;
    for (int i = 0; i < kLines; ++i) {
        ASSERT_TRUE(writer.write(ia, numbered("a", i)));
        ASSERT_TRUE(writer.write(ib, numbered("b", i)));
        if (i % 16 == 15)
            writer.flush();
    }
    writer.flush();
    const std::vector<std::string> got_a = read_lines(dir_ / "a.csv");
    const std::vector<std::string> got_b = read_lines(dir_ / "b.jsonl");
    ASSERT_EQ(got_a.size(), static_cast<std::size_t>(kLines)) << "flush() returned before the last line";
    ASSERT_EQ(got_b.size(), static_cast<std::size_t>(kLines));
    for (int i = 0; i < kLines; ++i) {
        EXPECT_EQ(got_a[i] + "\n", numbered("a", i));
        EXPECT_EQ(got_b[i] + "\n", numbered("b", i));
    }
    writer.stop();
    EXPECT_EQ(writer.counters(ia).written, static_cast<std::uint64_t>(kLines));
    EXPECT_EQ(writer.counters(ib).written, static_cast<std::uint64_t>(kLines));
    EXPECT_EQ(writer.counters(ia).lost(), 0u);
    EXPECT_EQ(writer.counters(ib).lost(), 0u);
    EXPECT_EQ(log.text(), "") << "nothing failed, nothing to say";
}

TEST_F(RecordWriterTest, EachLineWakesTheWriterWithoutAFlush)
{
    // The writer thread sleeps while the ring is empty; every line must
    // wake it, or a kill would lose lines queued long before it. The pipe
    // is read as the lines come, with no flush() and no stop(): each one
    // must arrive on its own, also after the writer went back to sleep.
    UnreadPipe pipe;
    ASSERT_GE(pipe.read_fd, 0);
    stemd::test::CapturedLog log;
    RecordWriter writer(16, log.logger);
    const std::size_t id = writer.add(pipe.file, "pipe");
    writer.start();
    for (int i = 0; i < 20; ++i) {
        const std::string line = numbered("w", i);
        ASSERT_TRUE(writer.write(id, line));
        // Far longer than a wake-up takes; without one, nothing comes.
        ASSERT_EQ(pipe.read_within(line.size(), 10'000), line) << "line " << i << " was not written";
    }
    writer.flush();   // the last line is read; its count may lag by the writer's last instructions
    EXPECT_EQ(writer.counters(id).written, 20u);
    writer.stop();
}

TEST_F(RecordWriterTest, AFileThatStopsTakingLinesHoldsUpOnlyTheWriter)
{
    UnreadPipe pipe;
    ASSERT_GE(pipe.read_fd, 0);
    ASSERT_GT(pipe.capacity_bytes, 0);
    stemd::test::CapturedLog log;
    constexpr int kLines = 200;
    RecordWriter writer(kLines, log.logger);
    const std::size_t id = writer.add(pipe.file, "pipe");
    writer.start();
    const std::string payload(999, 'x');
    // Every line is taken at once, although the pipe can hold only part of them.
    for (int i = 0; i < kLines; ++i)
        ASSERT_TRUE(writer.write(id, payload + "\n")) << "line " << i;
    const int pipe_lines = pipe.capacity_bytes / 1000;
    ASSERT_LT(pipe_lines, kLines);
    EXPECT_LE(writer.counters(id).written, static_cast<std::uint64_t>(pipe_lines));
    // Once the pipe is read, every line arrives, whole and in order.
    std::string received;
    std::thread reader([&] { received = pipe.read(static_cast<std::size_t>(kLines) * 1000 + 1); });
    writer.flush();
    writer.stop();
    pipe.file.close();   // the reader sees the end
    reader.join();
    EXPECT_EQ(received.size(), static_cast<std::size_t>(kLines) * 1000);
    EXPECT_EQ(received.find_first_not_of("x\n"), std::string::npos);
    EXPECT_EQ(writer.counters(id).written, static_cast<std::uint64_t>(kLines));
    EXPECT_EQ(writer.counters(id).lost(), 0u);
}

TEST_F(RecordWriterTest, AFileThatTakesNothingWithinTheTimeoutStallsTheFlush)
{
    UnreadPipe pipe;
    ASSERT_GE(pipe.read_fd, 0);
    stemd::test::CapturedLog log;
    constexpr int kLines = 200;
    RecordWriter writer(kLines, log.logger);
    const std::size_t id = writer.add(pipe.file, "pipe");
    writer.start();
    const std::string line(999, 'x');
    for (int i = 0; i < kLines; ++i)
        ASSERT_TRUE(writer.write(id, line + "\n"));
    // Nobody reads: the pipe takes its 64 KiB and the writer waits in write(2).
    EXPECT_FALSE(writer.flush(100'000'000));
    EXPECT_TRUE(writer.stalled());
    EXPECT_GE(writer.unwritten(), static_cast<std::uint64_t>(kLines - pipe.capacity_bytes / 1000));
    EXPECT_FALSE(writer.flush()) << "a stalled writer is not waited for again";
    // Read after all: the thread's write returns, it takes the rest, and
    // stop() can join it.
    std::size_t received = 0;
    std::thread reader([&] { received = pipe.read(static_cast<std::size_t>(kLines) * 1000).size(); });
    reader.join();
    writer.stop(60'000'000'000);
    EXPECT_FALSE(writer.running()) << "the thread ended once its file took the lines";
    EXPECT_EQ(received, static_cast<std::size_t>(kLines) * 1000);
    EXPECT_EQ(writer.counters(id).written, static_cast<std::uint64_t>(kLines));
    EXPECT_NE(log.text().find("pipe: " + std::to_string(writer.unwritten()) +
                              " lines not written: the file did not take them within 100 ms"),
              std::string::npos)
        << log.text();
}

TEST_F(RecordWriterTest, AFullRingDropsTheLineAndCountsIt)
{
    RecordFile file;
    ASSERT_EQ(file.open((dir_ / "map.jsonl").c_str()), 0);
    stemd::test::CapturedLog log;
    RecordWriter writer(4, log.logger);   // not started: nothing drains the ring
    const std::size_t id = writer.add(file, "map.jsonl");
    for (int i = 0; i < 6; ++i)
        EXPECT_EQ(writer.write(id, numbered("line ", i)), i < 4) << i;
    EXPECT_EQ(writer.counters(id).dropped, 2u);
    // Without a thread, flush() writes on the caller's.
    writer.flush();
    const std::vector<std::string> got = read_lines(dir_ / "map.jsonl");
    ASSERT_EQ(got.size(), 4u);
    EXPECT_EQ(got.back(), "line 3");
    writer.stop();
    EXPECT_EQ(writer.counters(id).lost(), 2u);
    EXPECT_NE(log.text().find("map.jsonl: 2 lines lost (0 failed writes, 2 to a full queue), 4 written"),
              std::string::npos)
        << log.text();
}

TEST_F(RecordWriterTest, ALineLongerThanACellIsDroppedNotCut)
{
    RecordFile file;
    ASSERT_EQ(file.open((dir_ / "out.csv").c_str()), 0);
    stemd::test::CapturedLog log;
    RecordWriter writer(8, log.logger);
    const std::size_t id = writer.add(file, "out.csv");
    EXPECT_FALSE(writer.write(id, std::string(RecordWriter::kLineBytes + 1, 'y')));
    EXPECT_TRUE(writer.write(id, std::string(RecordWriter::kLineBytes - 1, 'z') + "\n"));
    writer.stop();
    const std::vector<std::string> got = read_lines(dir_ / "out.csv");
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(got[0], std::string(RecordWriter::kLineBytes - 1, 'z'));
    EXPECT_EQ(writer.counters(id).dropped, 1u);
}

TEST_F(RecordWriterTest, AFailedWriteIsLoggedOnceWithItsErrnoAndLaterLinesAreTried)
{
    RecordFile file;
    ASSERT_EQ(file.open("/dev/full"), 0);   // every write: ENOSPC
    stemd::test::CapturedLog log;
    RecordWriter writer(16, log.logger);
    const std::size_t id = writer.add(file, "/dev/full");
    writer.start();
    for (int i = 0; i < 3; ++i)
        ASSERT_TRUE(writer.write(id, numbered("l", i)));
    writer.flush();
    writer.stop();
    const RecordWriter::FileCounters c = writer.counters(id);
    EXPECT_EQ(c.failed, 3u);
    EXPECT_EQ(c.written, 0u);
    EXPECT_EQ(c.first_error, ENOSPC);
    const std::string text = log.text();
    const std::string failure = "/dev/full: write failed: No space left on device (errno 28)";
    const std::size_t first = text.find(failure);
    ASSERT_NE(first, std::string::npos) << text;
    EXPECT_EQ(text.find("write failed", first + failure.size()), std::string::npos) << "logged more than once:\n"
                                                                                    << text;
    EXPECT_NE(text.find("/dev/full: 3 lines lost (3 failed writes, 0 to a full queue), 0 written"), std::string::npos)
        << text;
}

}  // namespace
