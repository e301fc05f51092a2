#include "stemd/runtime/record_output.hpp"

#include <cerrno>
#include <cstring>
#include <utility>

namespace stemd::runtime {

RecordOutput::RecordOutput(std::string what, std::shared_ptr<spdlog::logger> log)
    : what_(std::move(what)), log_(std::move(log))
{
}

RecordOutput::~RecordOutput()
{
    close();
}

bool RecordOutput::open(const std::filesystem::path& path, std::string_view header)
{
    path_ = path;
    int err = file_.open(path.c_str());
    if (err == 0 && !header.empty())
        err = file_.write(header);
    if (err != 0) {
        log_->error("{}: cannot create the {}: {} (errno {})", path.string(), what_, std::strerror(err), err);
        file_.close();
        return false;
    }
    return true;
}

void RecordOutput::attach(RecordWriter& writer)
{
    if (!file_.is_open())
        return;
    writer_file_ = writer.add(file_, path_.string());
    writer_ = &writer;
}

bool RecordOutput::lose(int err)
{
    if (!lost_)
        log_->error("{}: {} line lost: {} (errno {}); later lines are still tried", path_.string(), what_,
                    std::strerror(err), err);
    lost_ = true;
    return false;
}

bool RecordOutput::write(std::string_view line)
{
    if (!file_.is_open())
        return true;
    if (writer_ != nullptr)
        return writer_->write(writer_file_, line);   // a lost line is counted and logged by the writer
    if (const int err = file_.write(line); err != 0)
        return lose(err);
    return true;
}

bool RecordOutput::close()
{
    if (writer_ != nullptr && file_.is_open()) {
        if (!writer_->flush(RecordWriter::kCloseTimeoutNs))
            return false;   // left open: see stalled()
        if (writer_->counters(writer_file_).lost() > 0)
            lost_ = true;
    }
    file_.close();
    return !lost_;
}

}  // namespace stemd::runtime
