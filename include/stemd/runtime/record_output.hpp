// One of the daemon's optional line files (the detections' CSV, the plant
// map): the file, where its lines go, and whether any was lost. Before
// attach() (tests, tools) write() makes the write(2) itself; after it the
// line is queued for the writer thread (record_writer.hpp), which then owns
// the errors: it counts and logs them per file.
//
// A line is given whole or not at all (base::RecordFile): a line that could
// not be formatted or written is lost, logged once per file, and later
// lines are still tried, as the writer thread does. Nothing allocates after
// open().
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include <spdlog/logger.h>

#include "stemd/base/record_file.hpp"
#include "stemd/runtime/record_writer.hpp"

namespace stemd::runtime {

class RecordOutput {
public:
    // `what` names the file in log lines ("plant map").
    RecordOutput(std::string what, std::shared_ptr<spdlog::logger> log);
    ~RecordOutput();   // close()
    RecordOutput(const RecordOutput&) = delete;
    RecordOutput& operator=(const RecordOutput&) = delete;

    // Creates (truncates) the file and writes `header` (a whole line, when
    // not empty); false, logged with the path and errno, if it cannot.
    bool open(const std::filesystem::path& path, std::string_view header = {});
    bool is_open() const { return file_.is_open(); }

    // After open(): lines go through `writer`, which must outlive close().
    void attach(RecordWriter& writer);

    // One whole line; false if it was lost (see above). No allocation.
    bool write(std::string_view line);
    // A line that could not be made (too long for its buffer): lost like a
    // failed write, with `err` (EOVERFLOW). Returns false.
    bool lose(int err);

    // Waits for the writer's last line of this file (at most
    // RecordWriter::kCloseTimeoutNs), then closes; false if any line was
    // lost. If the writer stalled, the file is left open: the writer thread
    // may be in a write(2) on it, so this must then not be destroyed
    // (stalled()).
    bool close();
    bool stalled() const { return writer_ != nullptr && writer_->stalled(); }

private:
    std::string what_;
    std::shared_ptr<spdlog::logger> log_;
    std::filesystem::path path_;
    base::RecordFile file_;
    RecordWriter* writer_ = nullptr;
    std::size_t writer_file_ = 0;
    bool lost_ = false;
};

}  // namespace stemd::runtime
