// stemd-record: writes what the configured frame source (source.kind: v4l2,
// libcamera or replay) delivers into a recording directory (frames.csv +
// rgb/NNNNNN.png, see include/stemd/io/recording.hpp), so that field runs
// can be replayed by the daemon and the tools.
//   stemd-record [--config FILE] [--set KEY=VALUE]... --out DIR
//                [--frames N] [--seconds S] [--replay DIR] [--slots N]
//
// Threads: the main thread captures (source->next into preallocated slots
// from a FramePool) and hands full slots to a writer thread through an
// SpscRing; the writer (io::RecordingWriter) encodes the PNGs, appends the
// frames.csv row (one whole line per write(2), so a kill tears none) and
// gives the slot back through a second ring. The capture loop
// never waits for the disk: with a camera (a realtime source) a frame that
// finds no free slot is dropped and counted; a source that can wait (fast
// replay) waits instead and loses nothing.
//
// t_ns is the frame's t_sample_ns (CLOCK_MONOTONIC). A replay source plays
// its recording once. nir/ and mask/ are written when the source fills those
// planes (replay of a recording that has them, with segment.method ndvi/mask);
// the odom_mm and class columns (class/NNNNNN.png) when the replayed
// recording has them. With odometry.source can or encoder, odom_mm is the
// machine's odometer at each capture, from the ODOMETRY frames on
// can.interface or the wheel encoder (runtime::OdometerTap, on a thread of
// its own); the writer thread asks
// for it, so waiting for the sample after a capture never holds up the
// capture loop.
//
// Exit: 0 after N frames, S seconds, SIGINT/SIGTERM or the end of a replayed
// recording; 1 when the source or the disk fails; 2 on bad arguments or
// configuration, or when DIR exists and is not empty or cannot be created.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <spdlog/spdlog.h>

#include "stemd/drivers/frame_source.hpp"
#include "stemd/config/config.hpp"
#include "stemd/runtime/actuation_factory.hpp"
#include "stemd/runtime/daemon_config.hpp"
#include "stemd/runtime/frame_pool.hpp"
#include "stemd/runtime/logging.hpp"
#include "stemd/runtime/signals.hpp"
#include "stemd/runtime/source_factory.hpp"
#include "stemd/base/spsc_ring.hpp"
#include "stemd/runtime/status.hpp"
#include "stemd/io/recording.hpp"
#include "stemd/io/recording_writer.hpp"
#include "tool_cli.hpp"
#include "stemd/base/clock.hpp"

using namespace stemd;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

namespace {

using tools::kUsageError;
constexpr long kDefaultSlots = 8;

const char* const kUsage =
    "usage: stemd-record [--config FILE] [--set KEY=VALUE]... --out DIR\n"
    "                    [--frames N] [--seconds S] [--replay DIR] [--slots N]\n"
    "  --config   configuration file (see config/stemd.yaml); source.* picks the camera\n"
    "  --set      override one configuration key, e.g. --set source.kind=v4l2\n"
    "  --out      the recording directory to create (must not exist or be empty)\n"
    "  --frames   stop after N frames recorded\n"
    "  --seconds  stop after S seconds\n"
    "  --replay   record a recording directory (overrides source.*; played once)\n"
    "  --slots    frames buffered between capture and the PNG writer (default 8)\n"
    "Stops on SIGINT/SIGTERM too; frames the writer cannot keep up with are dropped and counted.\n";

struct Args {
    config::ConfigArgs config;
    std::string out;
    long frames = 0;      // 0: no limit
    double seconds = 0;   // 0: no limit
    std::string replay_dir;
    long slots = kDefaultSlots;
};

const tools::CommandLine kCommandLine{.tool = "stemd-record", .usage = kUsage, .usage_after_error = true};

// The arguments into `args` and the configuration they name into `config`;
// the exit code after --help, a usage error or a configuration error.
std::optional<int> parse_args(int argc, char** argv, Args& args, config::Config& config)
{
    CLI::App app{"stemd-record"};
    tools::add_config_options(app, args.config);
    app.add_option("--out", args.out);
    app.add_option("--frames", args.frames)
        ->check(tools::value_check<long>("a positive integer", [](long n) { return n >= 1; }));
    app.add_option("--seconds", args.seconds)
        ->check(tools::value_check<double>("a positive number", [](double s) { return s > 0; }));
    app.add_option("--replay", args.replay_dir);
    app.add_option("--slots", args.slots)
        ->check(tools::value_check<long>("an integer in [2, 1024]", [](long n) { return n >= 2 && n <= 1024; }));
    if (const auto exit_code = tools::parse(app, argc, argv, kCommandLine))
        return *exit_code;
    if (args.out.empty())
        return tools::usage_error(kCommandLine, "--out DIR is required");
    return tools::load_config(kCommandLine, args.config, config);
}

// Refuses a `dir` that exists and is not an empty directory: a recording
// is never overwritten.
bool check_out_dir(const fs::path& dir, std::string& error)
{
    std::error_code ec;
    if (!fs::exists(dir, ec))
        return true;
    if (!fs::is_directory(dir, ec)) {
        error = dir.string() + " exists and is not a directory: refusing to overwrite it";
        return false;
    }
    if (!fs::is_empty(dir, ec) || ec) {
        error = dir.string() + " exists and is not empty: refusing to overwrite a recording";
        return false;
    }
    return true;
}

// The optional columns a replayed recording carries, so that its copy keeps
// them. A recording the reader refuses has none here: the replay source
// then reports it when it opens.
io::RecordingColumns replayed_columns(const fs::path& replay_dir)
{
    io::RecordingColumns columns;
    std::string error;
    const auto recording = io::read_recording(replay_dir, error);
    if (!recording)
        return columns;
    for (const io::RecordingFrame& frame : recording->frames) {
        columns.odom_mm = columns.odom_mm || frame.odom_mm.has_value();
        columns.plant_class = columns.plant_class || !frame.plant_class.empty();
    }
    return columns;
}

// What a slot holds as a frames.csv row: t_ns is the sample (exposure) time, and only
// a class map the source filled is written.
io::FrameToWrite to_write(const drivers::Frame& frame)
{
    return {.t_ns = frame.t_sample_ns,
            .bgr = frame.bgr,
            .nir = frame.nir,
            .mask = frame.mask,
            .odom_mm = std::isnan(frame.odom_mm) ? std::nullopt : std::optional<double>(frame.odom_mm),
            .plant_class = frame.has_class_map ? frame.plant_class : cv::Mat()};
}

// The odometer at a frame's capture from the drive's ODOMETRY, waiting a
// millisecond at a time for the sample after it (the tap bounds the wait);
// NaN when it cannot be known, an empty odom_mm cell.
double odometer_at_capture(runtime::OdometerTap& odometer, std::int64_t t_sample_ns)
{
    for (;;) {
        double odom_mm = 0;
        switch (odometer.odometer_at(t_sample_ns, base::monotonic_ns(), odom_mm)) {
        case runtime::OdometerTap::Reading::known: return odom_mm;
        case runtime::OdometerTap::Reading::unknown: return std::numeric_limits<double>::quiet_NaN();
        case runtime::OdometerTap::Reading::wait: std::this_thread::sleep_for(1ms); break;
        }
    }
}

}  // namespace

int main(int argc, char** argv)
{
    Args args;
    config::Config config;
    if (const auto exit_code = parse_args(argc, argv, args, config))
        return *exit_code;
    // Before the writer thread exists, so that only the capture loop sees SIGTERM/SIGINT.
    runtime::ShutdownSignals signals;

    std::string error;
    runtime::DaemonConfig daemon_config = config.settings().daemon;
    if (!args.replay_dir.empty()) {
        daemon_config.source_kind = "replay";
        daemon_config.replay_dir = args.replay_dir;
    }
    daemon_config.replay_loop = false;   // a recording is recorded once
    if (const auto problem = runtime::check_source_config(daemon_config, config, !args.replay_dir.empty())) {
        std::cerr << "stemd-record: " << *problem << "\n";
        return kUsageError;
    }
    // Cameras deliver bgr only; a replay fills the planes the segmentation reads.
    runtime::resolve_auto_segmentation(daemon_config);
    const vision::Segmentation planes =
        daemon_config.source_kind == "replay" ? daemon_config.vision.segmentation : vision::Segmentation::exg;
    const fs::path out = args.out;
    io::RecordingColumns columns;
    if (daemon_config.source_kind == "replay")
        columns = replayed_columns(daemon_config.replay_dir);
    // The drive's odometer, recorded with each frame so that the recording
    // replays with the distance really travelled.
    const runtime::ActuationConfig& actuation = config.settings().actuation;
    std::unique_ptr<runtime::OdometerTap> odometer;
    if (actuation.odometry == runtime::OdometrySource::can || actuation.odometry == runtime::OdometrySource::encoder) {
        if (const auto problem = runtime::check_actuation_config(actuation)) {
            std::cerr << "stemd-record: " << config.blame(problem->key, problem->message) << "\n";
            return kUsageError;
        }
        odometer = runtime::make_odometer_tap(actuation, error);
        if (!odometer) {
            std::cerr << "stemd-record: " << error << "\n";
            return kUsageError;
        }
        columns.odom_mm = true;
    }
    columns.nir = vision::uses_nir(planes);
    columns.mask = planes == vision::Segmentation::mask;
    // Level 1: lossless like every level, and fast enough to keep up with a camera.
    const io::RecordingWriterOptions recording{.columns = columns, .png_compression_level = 1};
    io::RecordingWriter writer;
    if (!check_out_dir(out, error) || !writer.open(out, recording, error)) {
        std::cerr << "stemd-record: " << error << "\n";
        return kUsageError;
    }

    runtime::set_log_level(daemon_config.log_level);
    const auto log = runtime::make_logger("record");

    const auto slot_count = static_cast<std::size_t>(args.slots);
    std::unique_ptr<runtime::FramePool> pool;
    try {
        pool = std::make_unique<runtime::FramePool>(daemon_config.frame_size, planes, slot_count, columns.plant_class);
    } catch (const std::bad_alloc&) {
        log->error("cannot allocate {} frame slots of {}x{}", slot_count, daemon_config.frame_size.width,
                   daemon_config.frame_size.height);
        return 1;
    }
    // Both rings hold every slot, so a push never fails: free slots go
    // writer -> capture, full ones capture -> writer.
    base::SpscRing<drivers::Frame*> free_slots(slot_count);
    base::SpscRing<drivers::Frame*> full_slots(slot_count);
    for (std::size_t i = 1; i < slot_count; ++i)
        free_slots.try_push(&(*pool)[i]);
    drivers::Frame* hand = &(*pool)[0];

    const std::unique_ptr<drivers::FrameSource> source = runtime::make_frame_source(daemon_config);
    if (!source->open() || !source->start())
        return 1;
    const bool can_wait = !source->realtime();
    log->info("recording {} into {}", source->name(), out.string());
    if (odometer) {
        odometer->start();
        log->info("odometer: {} ({})", odometer->source_name(),
                  actuation.odometry == runtime::OdometrySource::can ? "ODOMETRY frames" : "wheel encoder");
    }
    std::uint64_t without_odometer = 0;   // the writer's

    std::atomic<bool> capture_done{false};
    std::atomic<bool> writer_failed{false};
    std::thread writer_thread([&] {
        drivers::Frame* frame = nullptr;
        for (;;) {
            if (!full_slots.try_pop(frame)) {
                // capture_done is set after the last push: seen set, an empty
                // ring means every frame has been taken.
                if (capture_done.load(std::memory_order_acquire) && !full_slots.try_pop(frame))
                    break;
                if (frame == nullptr) {
                    std::this_thread::sleep_for(1ms);
                    continue;
                }
            }
            if (odometer) {
                frame->odom_mm = odometer_at_capture(*odometer, frame->t_sample_ns);
                without_odometer += std::isnan(frame->odom_mm) ? 1 : 0;
            }
            std::string write_error;
            const bool ok = writer.append(to_write(*frame), write_error);
            free_slots.try_push(frame);
            frame = nullptr;
            if (!ok) {
                log->error("{}", write_error);
                writer_failed.store(true, std::memory_order_release);
                break;
            }
        }
    });

    const std::int64_t t_start_ns = base::monotonic_ns();
    const std::int64_t t_end_ns =
        args.seconds > 0 ? t_start_ns + static_cast<std::int64_t>(args.seconds * 1e9) : INT64_MAX;
    bool stop_signalled = false;
    auto stop_requested = [&] {
        if (!stop_signalled) {
            if (const auto sig = signals.wait(0ms)) {
                log->info("{}: stopping", *sig == SIGTERM ? "SIGTERM" : "SIGINT");
                stop_signalled = true;
            }
        }
        return stop_signalled || writer_failed.load(std::memory_order_acquire);
    };
    std::uint64_t queued = 0;
    std::uint64_t writer_behind = 0;   // frames dropped: no free slot
    int exit_code = 0;
    while (!stop_requested()) {
        if (args.frames > 0 && queued >= static_cast<std::uint64_t>(args.frames))
            break;
        const std::int64_t now_ns = base::monotonic_ns();
        if (now_ns >= t_end_ns)
            break;
        const auto timeout = std::chrono::nanoseconds(std::min<std::int64_t>(t_end_ns - now_ns, 100'000'000));
        const drivers::NextStatus status = source->next(*hand, timeout);
        if (status == drivers::NextStatus::timeout || status == drivers::NextStatus::skipped)
            continue;
        if (status == drivers::NextStatus::end_of_stream)
            break;
        if (status == drivers::NextStatus::failed) {
            log->error("{}: failed; recording stops", source->name());
            exit_code = 1;
            break;
        }
        drivers::Frame* next = nullptr;
        if (!free_slots.try_pop(next)) {
            if (!can_wait) {
                ++writer_behind;   // `hand` is reused for the next frame
                continue;
            }
            while (!free_slots.try_pop(next) && !stop_requested())
                std::this_thread::sleep_for(1ms);
            if (next == nullptr)
                break;
        }
        full_slots.try_push(hand);
        hand = next;
        ++queued;
    }
    capture_done.store(true, std::memory_order_release);
    writer_thread.join();
    source->stop();
    if (odometer) {
        odometer->stop();
        const runtime::OdometerTapCounters o = odometer->counters();
        log->info("odometer: {} frames without a reading; samples: {} taken, {} rejected, {} going backwards, {} "
                  "dropped",
                  without_odometer, o.samples, o.rejected, o.backwards, o.dropped);
    }
    if (writer_failed.load(std::memory_order_acquire))
        exit_code = 1;

    const double run_s = static_cast<double>(base::monotonic_ns() - t_start_ns) / 1e9;
    const drivers::SourceCounters c = source->counters();
    if (writer_behind > 0)
        log->warn("{} frames dropped: the PNG writer could not keep up (try --slots or a faster disk)", writer_behind);
    std::fprintf(stderr,
                 "stemd-record: total: %" PRIu64 " frames written to %s in %.1f s | drops: writer_behind %" PRIu64
                 ", corrupt %" PRIu64 ", bad_size %" PRIu64 "\n",
                 writer.frames_written(), out.c_str(), run_s, writer_behind, c.corrupt, c.bad_size);
    return exit_code;
}
