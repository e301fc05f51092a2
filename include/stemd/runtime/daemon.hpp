// The daemon's three real-time threads and what connects them (and the writer
// thread of the optional files, below):
//
//   capture ──SpscRing<Frame*> (ring.capacity)──► processing ──SpscRing<FrameResult>──► actuator
//      ▲                                              │        (ring.results_capacity)
//      └──────────── SpscRing<Frame*> (free slots) ◄──┘
//   capture ──SpscRing<OdomSample> (a recording's odom_mm, at capture)──► actuator
//
// Frame slots (FramePool, ring.capacity + 2 of them) circulate as pointers:
// capture fills one from the source, processing runs vision::detect() on it
// and returns it to the free ring. With capacity + 2 slots the capture thread
// always finds a free one (at most `capacity` wait, one is processed, one is
// being filled), so overflow happens only when pushing into a full ring:
//   - drop_newest: the new frame is not pushed; its slot is reused (counted
//     by the ring as dropped);
//   - overwrite_oldest: the oldest waiting frame is taken back and its slot
//     reused (counted as overwritten).
// A source that can wait (fast replay) gets back-pressure instead: nothing
// is dropped.
//
// The optional outputs (the detections' CSV, the plant map) are formatted
// by the actuator and written by a fourth thread, the writer
// (record_writer.hpp), at normal priority.
//
// Per frame, once running, no thread allocates, locks or does blocking I/O
// (the replay source's PNG decoding and the CAN log's one write(2) per
// frame aside: see drivers/replay/replay_source.hpp and
// drivers/canlog/canlog_bus.hpp). Idle threads
// poll their ring with a short spin then 100 us sleeps, which bounds the
// added latency without a futex on the producer's side.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>

#include <spdlog/logger.h>

#include "stemd/drivers/frame_source.hpp"
#include "stemd/geometry/odometry.hpp"
#include "stemd/base/triple_buffer.hpp"
#include "stemd/runtime/actuation_stage.hpp"
#include "stemd/runtime/class_provider.hpp"
#include "stemd/runtime/daemon_config.hpp"
#include "stemd/runtime/detection_sink.hpp"
#include "stemd/runtime/frame_pool.hpp"
#include "stemd/runtime/live_feed.hpp"
#include "stemd/runtime/record_writer.hpp"
#include "stemd/base/spsc_ring.hpp"
#include "stemd/runtime/status.hpp"
#include "stemd/vision/detect.hpp"

namespace stemd::runtime {

class Daemon {
public:
    // Allocates everything the threads will use: slots, rings, workspace.
    // `actuation` is optional (nullptr: detections are only logged / written
    // as CSV); when given, the actuator thread drives it.
    Daemon(const DaemonConfig& config, std::unique_ptr<drivers::FrameSource> source,
           std::unique_ptr<DetectionSink> sink, std::unique_ptr<ActuationStage> actuation = nullptr);
    ~Daemon();   // stops and joins
    Daemon(const Daemon&) = delete;
    Daemon& operator=(const Daemon&) = delete;

    // Opens and starts the source, then the threads with their real-time
    // settings. False if the source cannot be opened (logged). Failures of
    // the real-time settings and of mlockall are warned about once, and the
    // daemon runs without them.
    bool start();

    // Before start(): where plants' classes come from (class_provider.hpp);
    // without a call, a recording's class column (RecordingClassProvider).
    // A provider that gives every result classes (the model, a socket)
    // makes the scheduler's auto policy treat weeds only. A model must fit
    // the configuration (checked by the caller: PlantClassifier::mismatch).
    void set_class_provider(std::unique_ptr<ClassProvider> provider);
    const ClassProvider& class_provider() const { return *classes_; }

    // Before start(): the live view's feed (owned by the caller, outliving
    // the threads). The processing thread lends it frames when a viewer
    // wants them (and takes the feed's in exchange: the feed must have the
    // pool's shape, or std::invalid_argument), the actuator the plants
    // whose tracks ended.
    void attach_live_feed(LiveFeed* feed);

    // From the live view's threads (any thread but the real-time ones): the
    // pipeline's parameters from the next frame on. The processing thread
    // takes them at a frame's start from a triple buffer allocated here,
    // without locking; concurrent callers are serialised among themselves.
    void set_vision_params(const vision::Params& params);
    // The operator's software disable (the live view): while set, no target
    // is sent, whatever the enable input says; clearing it only gives the
    // enable input back its say. Any thread.
    void set_operator_disabled(bool disabled);
    bool operator_disabled() const;
    // The enable input (GPIO; true without one). Any thread.
    bool enable_input() const;

    // From any thread; the threads finish their current frame and exit.
    void request_stop();
    // A finite source ended and every frame it delivered went through the
    // actuator; or the source failed. The caller then joins.
    bool finished() const { return actuator_done_.load(std::memory_order_acquire); }
    bool source_failed() const { return source_failed_.load(std::memory_order_acquire); }
    // A thread ended on an exception (std::bad_alloc under a memory limit,
    // say): written to stderr as one line naming the thread, and every
    // thread stops. The caller then joins and exits non-zero.
    bool thread_failed() const { return thread_failed_.load(std::memory_order_acquire); }
    // Joins the threads and closes the sink and the plant map; false if
    // either lost data.
    bool join();
    // After join(): an optional file did not take its last lines in time
    // (RecordWriter::stalled()); its writer thread may be blocked in
    // write(2) for good. The caller then ends the process without
    // destructors (stemd: _Exit(1)); this daemon leaks its writer and sink
    // if it is destroyed.
    bool output_stalled() const { return writer_ && writer_->stalled(); }

    StatusSnapshot snapshot(bool whole_run);

    // Liveness for the systemd watchdog: each thread stamps CLOCK_MONOTONIC
    // on every pass of its loop, idle waits included. The first thread whose
    // stamp is older than max_age_ns (a stuck thread), or nullptr.
    const char* stalled_thread(std::int64_t now_ns, std::int64_t max_age_ns) const;
    const Counters& counters() const { return *counters_; }
    // The actuation's counters, or nullptr without actuation.
    const ActuationCounters* actuation_counters() const { return actuation_ ? &actuation_->counters() : nullptr; }
    std::size_t pool_bytes() const { return pool_.bytes(); }
    std::size_t workspace_bytes() const { return workspace_->reserved_bytes(); }

private:
    void capture_loop();
    void processing_loop();
    void actuator_loop();
    bool stopping() const { return stop_.load(std::memory_order_acquire); }
    enum Thread { kCapture, kProcessing, kActuator, kThreads };
    void beat(Thread thread);
    // Runs a thread's loop; an exception out of it is reported, not
    // std::terminate (see thread_failed()).
    void guarded(Thread thread, void (Daemon::*loop)());
    // For the HEARTBEAT: the source says it lost its camera, or has given
    // no frame for config.lost_after_ms while the capture thread waited on it.
    bool camera_lost(std::int64_t now_ns) const;

    const DaemonConfig config_;
    const std::shared_ptr<spdlog::logger> log_;
    const std::shared_ptr<spdlog::logger> capture_log_;
    const std::shared_ptr<spdlog::logger> processing_log_;
    // Before the sink and the actuation, whose files it writes: destroyed after them.
    std::unique_ptr<RecordWriter> writer_;   // nullptr without a CSV or a map
    const std::unique_ptr<drivers::FrameSource> source_;
    std::unique_ptr<DetectionSink> sink_;   // leaked when the output stalled
    const std::unique_ptr<Counters> counters_;
    const std::unique_ptr<ActuationStage> actuation_;

    FramePool pool_;
    base::SpscRing<drivers::Frame*> free_slots_;   // processing -> capture
    base::SpscRing<drivers::Frame*> frames_;       // capture -> processing
    base::SpscRing<FrameResult> results_;          // processing -> actuator, built in place
    base::SpscRing<geometry::OdomSample> captured_odometry_;   // capture -> actuator: frames' own odom_mm
    const std::unique_ptr<vision::Workspace> workspace_;   // the processing thread's
    std::unique_ptr<ClassProvider> classes_;
    bool classes_started_ = false;
    LiveFeed* live_feed_ = nullptr;
    base::TripleBuffer<vision::Params> vision_params_;   // writers -> processing thread
    std::mutex vision_params_writer_;                     // one writer at a time (never the processing thread)
    std::atomic<bool> operator_disabled_{false};          // without actuation: nothing to disable

    std::atomic<bool> stop_{false};
    std::atomic<bool> source_ended_{false};      // the source said end_of_stream (not a failure or a stop)
    std::atomic<bool> capture_done_{false};      // the source ended or failed: nothing more will be pushed
    std::atomic<bool> processing_done_{false};
    std::atomic<bool> actuator_done_{false};
    std::atomic<bool> source_failed_{false};
    std::atomic<bool> thread_failed_{false};
    std::atomic<bool> sink_ok_{true};
    std::atomic<std::int64_t> alive_ns_[kThreads] = {};
    // Camera health, capture -> actuator: the source's own word (reopening,
    // failed), and when the capture thread last had no need of the source
    // (a frame came, or it was waiting for the pipeline instead); 0 before
    // the first frame.
    std::atomic<bool> source_lost_{false};
    std::atomic<std::int64_t> source_ok_ns_{0};
    std::thread capture_, processing_, actuator_;
    bool joined_ = false;
};

}  // namespace stemd::runtime
