// The optional outputs' lines (the detections' CSV, the plant map), written
// by a thread of their own. The actuator thread formats a line, copies it
// into a preallocated cell of a lock-free ring and goes on; the writer
// thread makes the write(2) (base::RecordFile: one per line). A disk that
// stalls (a page cache being written back to an SD card, a full NFS queue)
// then holds up no TARGET and no heartbeat.
//
// What that costs, and how it is bounded:
//   - a kill (SIGKILL, a crash) can also lose the lines still in the ring:
//     each line wakes the writer thread (a futex wake, only when it waits),
//     so on a healthy disk those are the lines of the moment, the ones
//     being written; on a stalled disk, what it held back;
//   - a disk stalled for longer than the ring's capacity lasts loses lines:
//     each is counted (dropped) per file and logged once, never half written;
//   - a failed write (ENOSPC, EFBIG) is logged once per file with its errno
//     and counted; later lines are still tried.
// flush() (end of a run) waits until every queued line is written, so a
// file is closed only after its last line; for at most its timeout. A file
// that has not taken them by then (a hung mount, a FIFO nobody reads) is
// stalled(): its lines still queued are given up, reported, and the writer
// thread, which may be blocked in write(2) on it, must then neither be
// joined nor have its files destroyed. The daemon ends the process instead
// (stemd exits 1 without running destructors; a blocked write(2) cannot be
// cancelled otherwise).
//
// One producer thread at a time: the daemon's actuator thread while it
// runs, the thread that joins it afterwards. Nothing allocates after add().
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <thread>

#include <spdlog/logger.h>

#include "stemd/base/record_file.hpp"
#include "stemd/base/spsc_ring.hpp"

namespace stemd::runtime {

class RecordWriter {
public:
    static constexpr std::size_t kLineBytes = 1024;   // longest line: the plant map's, under 768
    static constexpr std::size_t kMaxFiles = 4;
    // How often flush() and stop() look at the writer thread's progress.
    static constexpr std::int64_t kProgressPollNs = 250'000;
    // How long closing a file waits for its last lines at the end of a run
    // (a healthy disk takes the whole ring in milliseconds).
    static constexpr std::int64_t kCloseTimeoutNs = 3'000'000'000;

    struct FileCounters {
        std::uint64_t written = 0;   // lines the file took
        std::uint64_t failed = 0;    // lines a write(2) failed for
        std::uint64_t dropped = 0;   // lines lost to a full ring
        int first_error = 0;         // errno of the first failure, 0 if none
        std::uint64_t lost() const { return failed + dropped; }
    };

    // Allocates `capacity_lines` cells of kLineBytes.
    RecordWriter(std::size_t capacity_lines, std::shared_ptr<spdlog::logger> log);
    ~RecordWriter();   // stop()
    RecordWriter(const RecordWriter&) = delete;
    RecordWriter& operator=(const RecordWriter&) = delete;

    // Before start(): an open file that lines can go to (it must stay open
    // until flush() returned after its last line) and the name its errors
    // are logged under. Its index for write().
    std::size_t add(base::RecordFile& file, std::string name);

    // Starts the writer thread (named stemd-writer, the caller's scheduling).
    void start();
    bool running() const { return thread_.joinable(); }

    // Producer: queues a copy of `line` for `file`. False, counted as
    // dropped, if the ring is full or the line is longer than a cell. No
    // allocation, no lock, no system call.
    bool write(std::size_t file, std::string_view line) noexcept;

    // Producer: returns true once every line queued so far has been
    // written or has failed; false if that took longer than timeout_ns
    // (< 0: no limit), or an earlier flush timed out: then stalled().
    // Without a running thread (never started, or stopped), writes them on
    // the caller's thread.
    bool flush(std::int64_t timeout_ns = -1) noexcept;
    // A flush timed out: the writer thread may be blocked in write(2), and
    // `unwritten()` lines were still queued then.
    bool stalled() const { return stalled_.load(std::memory_order_acquire); }
    std::uint64_t unwritten() const { return unwritten_.load(std::memory_order_relaxed); }

    // Writes what is queued, then stops and joins the thread; logs each
    // file's losses (once). The writer can still take lines (flush()
    // writes them). Once stalled(), the thread is asked to stop and joined
    // only if it ends within stalled_wait_ns (its file took the lines
    // after all); else it is left as it is (the caller leaks the writer and
    // ends the process).
    void stop(std::int64_t stalled_wait_ns = 100'000'000) noexcept;

    FileCounters counters(std::size_t file) const;
    // Every file's added up (first_error: the first file's that has one).
    FileCounters totals() const;
    std::size_t capacity() const { return ring_.capacity(); }

private:
    struct Line {
        std::uint16_t file = 0;
        std::uint16_t length = 0;
        std::array<char, kLineBytes> text;
    };
    struct File {
        base::RecordFile* file = nullptr;
        std::string name;
        std::atomic<std::uint64_t> written{0};
        std::atomic<std::uint64_t> failed{0};
        std::atomic<std::uint64_t> queued{0};    // the producer's
        std::atomic<std::uint64_t> dropped{0};   // the producer's
        std::atomic<int> first_error{0};
        std::uint64_t dropped_logged = 0;        // the consumer's
    };

    void run();
    // Wakes the writer thread if it waits for lines.
    void wake() noexcept;
    // Consumer: writes every queued line; false if there was none.
    bool write_queued() noexcept;
    void report_drops() noexcept;

    const std::shared_ptr<spdlog::logger> log_;
    base::SpscRing<Line> ring_;
    std::array<File, kMaxFiles> files_;
    std::size_t n_files_ = 0;
    std::atomic<std::uint64_t> queued_{0};   // lines published (producer)
    std::atomic<std::uint64_t> done_{0};     // lines written or failed (consumer)
    // Changed at every line and at stop(); the writer thread waits on it
    // when the ring is empty. 32 bits: std::atomic waits on it with a
    // futex, not a mutex.
    std::atomic<std::uint32_t> wake_{0};
    std::atomic<bool> stop_{false};
    std::atomic<bool> stalled_{false};
    std::atomic<bool> finished_{false};   // run() returned
    std::atomic<std::uint64_t> unwritten_{0};
    bool losses_reported_ = false;
    std::thread thread_;
};

}  // namespace stemd::runtime
