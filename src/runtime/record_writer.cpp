#include "stemd/runtime/record_writer.hpp"

#include <pthread.h>

#include <cstring>
#include <stdexcept>

#include "stemd/base/clock.hpp"

namespace stemd::runtime {

RecordWriter::RecordWriter(std::size_t capacity_lines, std::shared_ptr<spdlog::logger> log)
    : log_(std::move(log)), ring_(capacity_lines)
{
}

RecordWriter::~RecordWriter()
{
    stop();
    // Stalled: the thread may be blocked in write(2) for good. The owner
    // should have leaked this writer and ended the process; detached, at
    // least the thread's end does not terminate it.
    if (thread_.joinable())
        thread_.detach();
}

std::size_t RecordWriter::add(base::RecordFile& file, std::string name)
{
    if (running())
        throw std::logic_error("RecordWriter::add after start()");
    if (n_files_ == kMaxFiles)
        throw std::length_error("RecordWriter: more than kMaxFiles files");
    File& f = files_[n_files_];
    f.file = &file;
    f.name = std::move(name);
    return n_files_++;
}

void RecordWriter::start()
{
    if (running())
        return;
    stop_.store(false, std::memory_order_relaxed);
    finished_.store(false, std::memory_order_relaxed);
    thread_ = std::thread([this] { run(); });
    // At most 15 characters; a failure only leaves the process's name.
    static_cast<void>(pthread_setname_np(thread_.native_handle(), "stemd-writer"));
}

bool RecordWriter::write(std::size_t file, std::string_view line) noexcept
{
    if (file >= n_files_)
        return false;
    File& f = files_[file];
    Line* cell = line.size() <= kLineBytes ? ring_.claim() : nullptr;
    if (cell == nullptr) {
        f.dropped.store(f.dropped.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
        return false;
    }
    cell->file = static_cast<std::uint16_t>(file);
    cell->length = static_cast<std::uint16_t>(line.size());
    std::memcpy(cell->text.data(), line.data(), line.size());
    f.queued.store(f.queued.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    ring_.publish();
    queued_.store(queued_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
    wake();
    return true;
}

void RecordWriter::wake() noexcept
{
    // A futex wake only while the writer thread waits; otherwise an atomic
    // add and a load.
    wake_.fetch_add(1, std::memory_order_release);
    wake_.notify_one();
}

bool RecordWriter::write_queued() noexcept
{
    bool any = false;
    while (Line* line = ring_.front()) {
        File& f = files_[line->file];
        const int err = f.file->write({line->text.data(), line->length});
        if (err == 0) {
            f.written.fetch_add(1, std::memory_order_relaxed);
        } else {
            if (f.failed.fetch_add(1, std::memory_order_relaxed) == 0) {
                f.first_error.store(err, std::memory_order_relaxed);
                log_->error("{}: write failed: {} (errno {}); later lines are still tried, the lost ones counted",
                            f.name, std::strerror(err), err);
            }
        }
        ring_.pop();
        done_.fetch_add(1, std::memory_order_release);
        any = true;
    }
    report_drops();
    return any;
}

void RecordWriter::report_drops() noexcept
{
    for (std::size_t i = 0; i < n_files_; ++i) {
        File& f = files_[i];
        const std::uint64_t dropped = f.dropped.load(std::memory_order_relaxed);
        if (f.dropped_logged == 0 && dropped > 0)
            log_->error("{}: lines lost: the disk took longer than the writer's {} queued lines last; the losses are "
                        "counted and reported at the end",
                        f.name, ring_.capacity());
        f.dropped_logged = dropped;
    }
}

void RecordWriter::run()
{
    for (;;) {
        // Read before looking at the ring: a line published after this
        // changes wake_, so the wait below returns at once.
        const std::uint32_t seen = wake_.load(std::memory_order_acquire);
        if (write_queued())
            continue;
        if (stop_.load(std::memory_order_acquire))
            break;
        wake_.wait(seen, std::memory_order_acquire);
    }
    write_queued();
    finished_.store(true, std::memory_order_release);
}

bool RecordWriter::flush(std::int64_t timeout_ns) noexcept
{
    if (stalled())
        return false;
    const std::uint64_t target = queued_.load(std::memory_order_relaxed);
    if (!running()) {
        write_queued();
        return true;
    }
    const std::int64_t give_up_ns = timeout_ns < 0 ? -1 : base::monotonic_ns() + timeout_ns;
    while (done_.load(std::memory_order_acquire) < target) {
        if (give_up_ns >= 0 && base::monotonic_ns() >= give_up_ns) {
            unwritten_.store(queued_.load(std::memory_order_relaxed) - done_.load(std::memory_order_acquire),
                             std::memory_order_relaxed);
            stalled_.store(true, std::memory_order_release);
            for (std::size_t i = 0; i < n_files_; ++i) {
                const File& f = files_[i];
                const std::uint64_t queued = f.queued.load(std::memory_order_relaxed);
                const std::uint64_t done = f.written.load(std::memory_order_relaxed) +
                                           f.failed.load(std::memory_order_relaxed);
                if (queued > done)
                    log_->error("{}: {} lines not written: the file did not take them within {} ms (a hung disk "
                                "or mount?); they are given up",
                                f.name, queued - done, timeout_ns / 1'000'000);
            }
            return false;
        }
        base::sleep_for_ns(kProgressPollNs);
    }
    return true;
}

void RecordWriter::stop(std::int64_t stalled_wait_ns) noexcept
{
    if (running()) {
        stop_.store(true, std::memory_order_release);
        wake();
        if (stalled()) {
            const std::int64_t give_up_ns = base::monotonic_ns() + stalled_wait_ns;
            while (!finished_.load(std::memory_order_acquire) && base::monotonic_ns() < give_up_ns)
                base::sleep_for_ns(kProgressPollNs);
            if (!finished_.load(std::memory_order_acquire))
                return;   // still in a write(2): left alone
        }
        thread_.join();
    }
    write_queued();
    if (losses_reported_)
        return;
    losses_reported_ = true;
    for (std::size_t i = 0; i < n_files_; ++i) {
        const FileCounters c = counters(i);
        if (c.lost() > 0)
            log_->error("{}: {} lines lost ({} failed writes, {} to a full queue), {} written", files_[i].name,
                        c.lost(), c.failed, c.dropped, c.written);
    }
}

RecordWriter::FileCounters RecordWriter::counters(std::size_t file) const
{
    FileCounters c;
    if (file >= n_files_)
        return c;
    const File& f = files_[file];
    c.written = f.written.load(std::memory_order_relaxed);
    c.failed = f.failed.load(std::memory_order_relaxed);
    c.dropped = f.dropped.load(std::memory_order_relaxed);
    c.first_error = f.first_error.load(std::memory_order_relaxed);
    return c;
}

RecordWriter::FileCounters RecordWriter::totals() const
{
    FileCounters sum;
    for (std::size_t i = 0; i < n_files_; ++i) {
        const FileCounters c = counters(i);
        sum.written += c.written;
        sum.failed += c.failed;
        sum.dropped += c.dropped;
        if (sum.first_error == 0)
            sum.first_error = c.first_error;
    }
    return sum;
}

}  // namespace stemd::runtime
