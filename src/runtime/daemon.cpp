#include "stemd/runtime/daemon.hpp"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <new>
#include <stdexcept>
#include <string>

#include <opencv2/core/utility.hpp>

#include "stemd/runtime/logging.hpp"
#include "stemd/runtime/thread_settings.hpp"
#include "stemd/runtime/trigger_clock.hpp"
#include "stemd/base/clock.hpp"

namespace stemd::runtime {

namespace {

using namespace std::chrono_literals;

// How long a source may block in next(): bounds how late a stop is noticed.
constexpr auto kSourceTimeout = 100ms;

// The writer's ring, in lines (1 KiB each): 4096 rows are 16 frames of 256
// plants, or several seconds of a normal field's output, for a disk to stall.
constexpr std::size_t kRecordWriterLines = 4096;

// Waiting for the other side of a ring: a short spin for the frame that is
// about to arrive, then 100 us sleeps. Sleeping keeps an idle thread off a
// CPU the pipeline needs (2 cores) and bounds the added latency at ~0.1 ms.
class Idle {
public:
    void wait()
    {
        if (++rounds_ < 64) {
            std::this_thread::yield();
            return;
        }
        base::sleep_for_ns(100'000);
    }
    void reset() { rounds_ = 0; }

private:
    int rounds_ = 0;
};

}  // namespace

Daemon::Daemon(const DaemonConfig& config, std::unique_ptr<drivers::FrameSource> source,
               std::unique_ptr<DetectionSink> sink, std::unique_ptr<ActuationStage> actuation)
    : config_(config),
      log_(make_logger("main")),
      capture_log_(make_logger("capture")),
      processing_log_(make_logger("processing")),
      source_(std::move(source)),
      sink_(std::move(sink)),
      counters_(std::make_unique<Counters>()),
      actuation_(std::move(actuation)),
      pool_(config.frame_shape(), config.ring_capacity + 2),
      free_slots_(config.ring_capacity + 2),
      frames_(config.ring_capacity),
      results_(config.results_capacity),
      // One sample per frame between capture and the actuator, and room to spare.
      captured_odometry_(2 * (config.ring_capacity + config.results_capacity + 4)),
      workspace_(std::make_unique<vision::Workspace>(config.frame_size, config.vision)),
      classes_(std::make_unique<RecordingClassProvider>()),
      vision_params_([&config](vision::Params& slot) { slot = config.vision; })
{
    for (std::size_t i = 0; i < pool_.size(); ++i)
        free_slots_.try_push(&pool_[i]);
    if (sink_->csv_open() || (actuation_ && actuation_->has_map())) {
        writer_ = std::make_unique<RecordWriter>(kRecordWriterLines, make_logger("writer"));
        sink_->attach(*writer_);
        if (actuation_)
            actuation_->attach_map_writer(*writer_);
    }
}

void Daemon::set_vision_params(const vision::Params& params)
{
    std::lock_guard lock(vision_params_writer_);
    vision_params_.write_slot() = params;
    vision_params_.publish();
}

void Daemon::set_operator_disabled(bool disabled)
{
    operator_disabled_.store(disabled, std::memory_order_relaxed);
    if (actuation_)
        actuation_->set_operator_disabled(disabled);
}

bool Daemon::operator_disabled() const { return operator_disabled_.load(std::memory_order_relaxed); }

bool Daemon::enable_input() const { return actuation_ ? actuation_->enable_input_seen() : true; }

void Daemon::attach_live_feed(LiveFeed* feed)
{
    if (feed != nullptr && !(feed->shape() == pool_.shape()))
        throw std::invalid_argument("Daemon::attach_live_feed: the feed's frame slots are not the pool's shape");
    live_feed_ = feed;
    if (actuation_)
        actuation_->set_live_feed(feed);
}

void Daemon::set_class_provider(std::unique_ptr<ClassProvider> provider)
{
    classes_ = std::move(provider);
}

Daemon::~Daemon()
{
    request_stop();
    join();
    if (output_stalled()) {
        // The writer thread may still be in a write(2) to the sink's file.
        static_cast<void>(sink_.release());
        static_cast<void>(writer_.release());
    }
}

bool Daemon::start()
{
    if (!source_->open()) {
        log_->error("{}: cannot start the frame source", source_->name());
        return false;
    }
    log_->info("{} frame slots of {}x{} ({:.1f} MiB), frame ring {} ({}), result ring {}, workspace {:.1f} MiB",
               pool_.size(), config_.frame_size.width, config_.frame_size.height, pool_.bytes() / 1048576.0,
               frames_.capacity(),
               base::name_of(kOverflowPolicyNames, config_.overflow),
               results_.capacity(), workspace_->reserved_bytes() / 1048576.0);

    if (!classes_->start()) {
        log_->error("classify.provider {}: cannot start", classes_->name());
        return false;
    }
    classes_started_ = true;
    std::string failures;
    auto note = [&failures](const std::string& f) {
        if (!f.empty())
            failures += (failures.empty() ? "" : "; ") + f;
    };
    // Before the threads, so that their stacks are locked too.
    if (config_.mlockall)
        note(lock_all_memory());
    // From the source's start until the threads have their priorities, this
    // thread must not wait behind other load: see StartupPriority.
    const StartupPriority startup(
        std::max({config_.capture.fifo_priority, config_.processing.fifo_priority, config_.actuator.fifo_priority}));
    note(startup.failure());
    // After the lock, which can take seconds over a preloaded recording: a
    // paced replay's clock starts here, so its first frames are not late.
    if (!source_->start()) {
        log_->error("{}: cannot start the frame source", source_->name());
        return false;
    }
    // OpenCV's calls on these threads (the capture's colour conversion)
    // run on the calling thread: its own worker pool would inherit one
    // thread's CPU and priority, and run beside the three unaccounted. The
    // pipeline is made to fit one core (Benchmarks).
    cv::setNumThreads(1);
    // The optional outputs' writer: the normal priority of this thread.
    if (writer_)
        writer_->start();
    // Stamped now, so a thread not yet scheduled does not look stuck.
    for (auto& stamp : alive_ns_)
        stamp.store(base::monotonic_ns(), std::memory_order_relaxed);
    actuator_ = std::thread([this] { guarded(kActuator, &Daemon::actuator_loop); });
    processing_ = std::thread([this] { guarded(kProcessing, &Daemon::processing_loop); });
    capture_ = std::thread([this] { guarded(kCapture, &Daemon::capture_loop); });
    note(apply_thread_settings(actuator_, "stemd-actuator", config_.actuator));
    note(apply_thread_settings(processing_, "stemd-process", config_.processing));
    note(apply_thread_settings(capture_, "stemd-capture", config_.capture));
    if (!failures.empty())
        log_->warn("running without some real-time settings (needs CAP_SYS_NICE / CAP_IPC_LOCK): {}", failures);
    return true;
}

void Daemon::request_stop()
{
    stop_.store(true, std::memory_order_release);
}

bool Daemon::join()
{
    if (joined_)
        return sink_ok_.load();
    for (std::thread* t : {&capture_, &processing_, &actuator_})
        if (t->joinable())
            t->join();
    source_->stop();
    if (classes_started_)
        classes_->stop();
    joined_ = true;
    if (!sink_->close())
        sink_ok_.store(false);
    // The plant map was closed by the actuator's finish(), the CSV now:
    // nothing is left to write.
    if (writer_)
        writer_->stop();
    return sink_ok_.load();
}

void Daemon::guarded(Thread thread, void (Daemon::*loop)())
{
    static constexpr const char* kNames[kThreads] = {"capture", "processing", "actuator"};
    const char* what = "an unknown exception";
    try {
        (this->*loop)();
        return;
    } catch (const std::bad_alloc&) {
        what = "out of memory (a memory limit: ulimit -v, MemoryMax=?)";
    } catch (const std::exception& e) {
        what = e.what();
    } catch (...) {
    }
    // One line without allocating (the logger may be what ran out).
    std::fprintf(stderr, "stemd: %s thread: %s; stopping\n", kNames[thread], what);
    thread_failed_.store(true, std::memory_order_release);
    stop_.store(true, std::memory_order_release);
    // Done, so that neither the watchdog nor the others wait for it.
    std::atomic<bool>* const done[kThreads] = {&capture_done_, &processing_done_, &actuator_done_};
    done[thread]->store(true, std::memory_order_release);
}

void Daemon::beat(Thread thread)
{
    alive_ns_[thread].store(base::monotonic_ns(), std::memory_order_relaxed);
}

const char* Daemon::stalled_thread(std::int64_t now_ns, std::int64_t max_age_ns) const
{
    static constexpr const char* kNames[kThreads] = {"capture", "processing", "actuator"};
    // A thread that finished its work (end of a finite source) is not stuck.
    const bool done[kThreads] = {capture_done_.load(std::memory_order_acquire),
                                 processing_done_.load(std::memory_order_acquire),
                                 actuator_done_.load(std::memory_order_acquire)};
    for (int t = 0; t < kThreads; ++t)
        if (!done[t] && now_ns - alive_ns_[t].load(std::memory_order_relaxed) > max_age_ns)
            return kNames[t];
    return nullptr;
}

bool Daemon::camera_lost(std::int64_t now_ns) const
{
    if (source_lost_.load(std::memory_order_relaxed))
        return true;
    // A finite source that ended lost nothing; before the first frame the
    // state is Starting, however long the camera takes.
    const std::int64_t ok_ns = source_ok_ns_.load(std::memory_order_relaxed);
    if (ok_ns == 0 || capture_done_.load(std::memory_order_acquire))
        return false;
    return static_cast<double>(now_ns - ok_ns) > config_.lost_after_ms * 1e6;
}

void Daemon::capture_loop()
{
    drivers::Frame* hand = nullptr;
    Idle idle;
    const bool can_wait = !source_->realtime();
    std::uint64_t seq = 0;
    // The camera trigger, if any: one pulse per frame period, before the
    // wait for the frame it asks for (the pulse blocks for its width, about
    // 100 us: a GPIO ioctl, the only I/O here besides the source's).
    drivers::GpioLines* const trigger = actuation_ ? actuation_->trigger_lines() : nullptr;
    TriggerClock trigger_clock(static_cast<std::int64_t>(1e9 / config_.fps));
    // Logged once per loss, when this thread first sees it and when frames
    // come again.
    bool loss_logged = false;
    while (!stopping()) {
        beat(kCapture);
        auto timeout = std::chrono::nanoseconds(kSourceTimeout);
        if (trigger != nullptr) {
            const std::int64_t now_ns = base::monotonic_ns();
            if (trigger_clock.due(now_ns)) {
                const std::uint64_t late_before = trigger_clock.late();
                if (trigger->pulse(actuation_->trigger_pulse_us()))
                    bump(counters_->capture.trigger_pulses);
                else
                    bump(counters_->capture.trigger_failed);
                trigger_clock.fired(now_ns);
                bump(counters_->capture.trigger_late, trigger_clock.late() - late_before);
            }
            timeout = std::min(timeout, std::chrono::nanoseconds(trigger_clock.wait_ns(base::monotonic_ns())));
        }
        if (hand == nullptr && !free_slots_.try_pop(hand)) {
            // The pool is sized so that this cannot happen; count it if it does.
            bump(counters_->capture.no_free_slot);
            source_ok_ns_.store(base::monotonic_ns(), std::memory_order_relaxed);
            idle.wait();
            continue;
        }
        const drivers::NextStatus status = source_->next(*hand, timeout);
        source_lost_.store(source_->lost(), std::memory_order_relaxed);
        if (status != drivers::NextStatus::frame && !loss_logged && camera_lost(base::monotonic_ns())) {
            loss_logged = true;
            capture_log_->warn("{}: {}; HEARTBEAT state CAMERA_LOST until frames come again", source_->name(),
                               source_->lost() ? "the camera is lost" : "no frame for source.lost_after_ms");
        }
        if (status == drivers::NextStatus::timeout) {
            // A wait cut short for the next trigger pulse is not a timeout.
            if (timeout == kSourceTimeout)
                bump(counters_->capture.timeouts);
            continue;
        }
        if (status == drivers::NextStatus::skipped)
            continue;   // counted by the source
        if (status == drivers::NextStatus::end_of_stream) {
            source_ended_.store(true, std::memory_order_release);
            break;
        }
        if (status == drivers::NextStatus::failed) {
            capture_log_->error("{}: failed; capture stops", source_->name());
            source_lost_.store(true, std::memory_order_relaxed);
            source_failed_.store(true, std::memory_order_release);
            break;
        }
        const std::int64_t t_got_ns = base::monotonic_ns();
        if (loss_logged) {
            loss_logged = false;
            capture_log_->info("{}: frames again, after {} ms without one", source_->name(),
                               (t_got_ns - source_ok_ns_.load(std::memory_order_relaxed)) / 1'000'000);
        }
        source_ok_ns_.store(t_got_ns, std::memory_order_relaxed);
        hand->seq = seq++;
        bump(counters_->capture.frames);
        classes_->on_capture(*hand);
        // The recording's odometer reaches the actuator now, not after the
        // pipeline: a slow frame must not make the odometer look stale. A
        // full ring loses nothing, the frame carries the same sample.
        if (actuation_ && std::isfinite(hand->odom_mm))
            captured_odometry_.try_push({hand->t_sample_ns, hand->odom_mm});
        // The odometer ahead (a paced replay's next recorded sample): the
        // actuator interpolates up to it instead of extrapolating, so how
        // long this frame takes to process changes no decision.
        if (actuation_ && std::isfinite(hand->odom_next_mm))
            captured_odometry_.try_push({hand->t_next_ns, hand->odom_next_mm});
        if (can_wait) {
            // Back-pressure: only this thread fills the ring, so once there
            // is room the push cannot fail.
            bool waited = false;
            while (frames_.size() == frames_.capacity() && !stopping()) {
                beat(kCapture);
                source_ok_ns_.store(base::monotonic_ns(), std::memory_order_relaxed);
                waited = true;
                idle.wait();
            }
            idle.reset();
            if (waited)
                bump(counters_->capture.backpressure_waits);
            if (stopping())
                break;
            frames_.try_push(hand);
            hand = nullptr;
        } else if (config_.overflow == OverflowPolicy::drop_newest) {
            if (frames_.try_push(hand))   // a full ring counts the drop
                hand = nullptr;
        } else {
            drivers::Frame* evicted = nullptr;
            hand = frames_.try_push_overwrite(hand, evicted) ? evicted : nullptr;
        }
        counters_->capture.cycle.record(base::monotonic_ns() - t_got_ns);
    }
    capture_done_.store(true, std::memory_order_release);
}

void Daemon::processing_loop()
{
    Idle idle;
    const bool can_wait = !source_->realtime();
    vision::StageTimes times;
    drivers::Frame* frame = nullptr;
    std::size_t processed = 0;
    while (!stopping()) {
        if (config_.stall_processing_after_frames > 0 && processed >= config_.stall_processing_after_frames) {
            // A stuck thread on purpose (debug.*): no beat, so the watchdog
            // goes unfed; a stop still ends it, so tests can shut down.
            processing_log_->warn("debug.stall_processing_after_frames: stalling after {} frames", processed);
            while (!stopping())
                base::sleep_for_ns(10'000'000);
            break;
        }
        beat(kProcessing);
        if (!frames_.try_pop(frame)) {
            // capture_done_ is set after its last push: seen set, an empty
            // ring means everything has been taken.
            if (capture_done_.load(std::memory_order_acquire) && !frames_.try_pop(frame))
                break;
            if (frame == nullptr) {
                idle.wait();
                continue;
            }
        }
        idle.reset();
        const std::int64_t t_start_ns = base::monotonic_ns();
        FrameResult* result = results_.claim();
        // A source that can wait loses nothing downstream either: wait for
        // the actuator rather than drop the result.
        while (result == nullptr && can_wait && !stopping()) {
            beat(kProcessing);
            idle.wait();
            result = results_.claim();
        }
        idle.reset();
        if (result == nullptr) {
            bump(counters_->processing.results_full);
        } else {
            // The live view's parameter changes, if any, from this frame on.
            vision_params_.take();
            const vision::Params& params = vision_params_.read_slot();
            vision::detect({.bgr = frame->bgr, .nir = frame->nir, .mask = frame->mask}, params, *workspace_,
                           result->detections, &times);
            result->seq = frame->seq;
            result->t_sample_ns = frame->t_sample_ns;
            result->t_recorded_ns = frame->t_recorded_ns;
            result->t_result_ns = base::monotonic_ns();
            result->pipeline_ns = times.total_ns;
            result->name = frame->name;
            result->odom_mm = frame->odom_mm;
            result->has_class_map = false;
            result->classes_pending = false;
            if (result->detections.status == vision::DetectStatus::ok)
                classes_->classify(*frame, params, *workspace_, *result);
            bump(counters_->processing.frames);
            ++processed;
            counters_->processing.pipeline.record(times.total_ns);
            if (result->detections.status == vision::DetectStatus::ok) {
                if (result->detections.stats.no_vegetation)
                    bump(counters_->processing.no_vegetation);
                bump(counters_->processing.plants_over_capacity,
                     static_cast<std::uint64_t>(result->detections.stats.plants_over_capacity));
                results_.publish();
                // After the publish, so the copy of the plants and mask
                // delays no result; the actuator only reads the published
                // result, and this thread claims its cell again no sooner
                // than its next frame. The frame slot itself goes to the
                // feed, and the slot it gives back goes to the pool.
                if (live_feed_ != nullptr) {
                    const std::int64_t now_ns = base::monotonic_ns();
                    if (live_feed_->frame_due(now_ns))
                        frame = live_feed_->publish(frame, result->detections, workspace_->closed(),
                                                    result->plant_class.data(), result->has_class_map, now_ns);
                }
            } else {
                bump(counters_->processing.failed);
                if (processing_log_->should_log(spdlog::level::debug))
                    processing_log_->debug("frame {} {}: {}", frame->seq, frame->name.view(),
                                           vision::to_string(result->detections.status));
            }
        }
        // The free ring holds every slot, so this push cannot fail.
        free_slots_.try_push(frame);
        frame = nullptr;
        counters_->processing.cycle.record(base::monotonic_ns() - t_start_ns);
    }
    processing_done_.store(true, std::memory_order_release);
}

void Daemon::actuator_loop()
{
    Idle idle;
    std::int64_t next_poll_ns = 0;
    auto take_captured_odometry = [this] {
        geometry::OdomSample sample;
        while (captured_odometry_.try_pop(sample))
            actuation_->on_capture(sample.t_ns, sample.odom_mm);
    };
    while (!stopping()) {
        beat(kActuator);
        if (actuation_) {
            take_captured_odometry();
            // Received frames, encoder samples, the heartbeat: every ms is enough.
            const std::int64_t now_ns = base::monotonic_ns();
            if (now_ns >= next_poll_ns) {
                actuation_->poll(now_ns, camera_lost(now_ns));
                next_poll_ns = now_ns + 1'000'000;
            }
        }
        FrameResult* result = results_.front();
        if (result == nullptr) {
            if (processing_done_.load(std::memory_order_acquire) && results_.front() == nullptr)
                break;
            idle.wait();
            continue;
        }
        // Classes from another process wait here, not in the pipeline, up
        // to their timeout after capture (the provider decides; it never
        // blocks): the odometer, the heartbeat and the bus are still served.
        if (result->classes_pending && !classes_->resolve(*result, base::monotonic_ns())) {
            idle.wait();
            continue;
        }
        idle.reset();
        const std::int64_t t_start_ns = base::monotonic_ns();
        const std::int64_t latency_ns = t_start_ns - result->t_sample_ns;
        counters_->actuator.latency.record(latency_ns);
        if (actuation_) {
            // Published after the frame's sample: drained here, it is in.
            take_captured_odometry();
            actuation_->on_frame(*result, base::monotonic_ns());
        }
        // The detections' CSV is optional output: queued for the writer
        // once the frame's TARGETs are out.
        if (!sink_->consume(*result, latency_ns))
            bump(counters_->actuator.sink_errors);
        bump(counters_->actuator.stems, result->detections.plants.size() - static_cast<std::size_t>(result->detections.stats.stemless));
        bump(counters_->actuator.frames);
        results_.pop();
        counters_->actuator.cycle.record(base::monotonic_ns() - t_start_ns);
    }
    // A recording played to its end, not a stop: its last view's plants
    // still pass the tools.
    if (actuation_ && source_ended_.load(std::memory_order_acquire) && !stopping())
        actuation_->end_of_stream();
    if (actuation_ && !actuation_->finish())
        sink_ok_.store(false);
    actuator_done_.store(true, std::memory_order_release);
}

StatusSnapshot Daemon::snapshot(bool whole_run)
{
    const drivers::SourceCounters source = source_->counters();
    StatusSnapshot s;
    s.t_ns = base::monotonic_ns();
    s.frames_in = counters_->capture.frames.load(std::memory_order_relaxed);
    s.frames_out = counters_->actuator.frames.load(std::memory_order_relaxed);
    s.stems_out = counters_->actuator.stems.load(std::memory_order_relaxed);
    s.ring_full = frames_.dropped();
    s.overwritten = frames_.overwritten();
    s.results_full = counters_->processing.results_full.load(std::memory_order_relaxed);
    s.corrupt = source.corrupt;
    s.bad_size = source.bad_size;
    s.failed = counters_->processing.failed.load(std::memory_order_relaxed);
    s.no_vegetation = counters_->processing.no_vegetation.load(std::memory_order_relaxed);
    s.over_capacity = counters_->processing.plants_over_capacity.load(std::memory_order_relaxed);
    s.late = source.late;
    s.worst_lateness_ms = source.worst_lateness_ms;
    const ClassCounters& classes = classes_->counters();
    s.bad_class = classes.bad_class.load(std::memory_order_relaxed);
    s.class_socket = classes_->name() == "socket";
    s.class_maps = classes.maps.load(std::memory_order_relaxed);
    s.class_timeouts = classes.timeouts.load(std::memory_order_relaxed);
    s.class_bad_messages = classes.bad_messages.load(std::memory_order_relaxed);
    s.class_peers = classes.peers.load(std::memory_order_relaxed);
    s.class_model = classes_->name() == "model";
    s.weed_parts = classes.weed_parts.load(std::memory_order_relaxed);
    s.stemless_weeds = classes.stemless_weeds.load(std::memory_order_relaxed);
    s.weed_cover = classes.weed_cover.load(std::memory_order_relaxed);
    s.cells_over_budget = classes.cells_over_budget.load(std::memory_order_relaxed);
    s.frames_over_budget = classes.frames_over_budget.load(std::memory_order_relaxed);
    // The capture thread's count, not the source's: with a camera trigger
    // every wait is cut short at the next pulse, which the source would
    // count as a timeout.
    s.source_timeouts = counters_->capture.timeouts.load(std::memory_order_relaxed);
    s.source_errors = source.errors;
    s.source_reopens = source.reopens;
    s.trigger = actuation_ && actuation_->trigger_lines() != nullptr;
    s.trigger_pulses = counters_->capture.trigger_pulses.load(std::memory_order_relaxed);
    s.trigger_late = counters_->capture.trigger_late.load(std::memory_order_relaxed);
    s.trigger_failed = counters_->capture.trigger_failed.load(std::memory_order_relaxed);
    if (writer_) {
        const RecordWriter::FileCounters files = writer_->totals();
        s.files = true;
        s.file_lines_written = files.written;
        s.file_lines_lost = files.lost() + writer_->unwritten();
    }
    if (actuation_) {
        const ActuationCounters& a = actuation_->counters();
        const auto get = [](const std::atomic<std::uint64_t>& c) { return c.load(std::memory_order_relaxed); };
        s.actuation = true;
        s.targets = get(a.targets);
        s.sent = get(a.sent);
        s.deadline_misses = get(a.deadline_misses) + get(a.bus_deadline);
        s.not_treated = get(a.policy) + get(a.no_tool) + get(a.disabled) + get(a.not_ready);
        s.not_ready = get(a.not_ready);
        s.no_odometry = get(a.no_odometry);
        s.odometry_can = actuation_->odometry_source() == OdometrySource::can;
        s.odometry_encoder = actuation_->odometry_source() == OdometrySource::encoder;
        s.rx_odometry = get(a.rx_odometry);
        s.odometry_going_back = get(a.odometry_going_back);
        if (a.rx_tool_status.load(std::memory_order_acquire) > 0) {
            s.tool_status = true;
            s.tools_ready_mask = static_cast<std::uint16_t>(get(a.tools_ready_mask));
            s.tool_error_code = static_cast<std::uint8_t>(get(a.tool_error_code));
            s.tool_status_age_ms =
                static_cast<double>(s.t_ns - a.tool_status_rx_ns.load(std::memory_order_relaxed)) / 1e6;
        }
        if (actuation_->on_can_interface()) {
            const drivers::CanBusCounters bus = actuation_->bus().counters();
            s.can_interface = true;
            s.can_tx_late = bus.tx_late;
            s.can_tx_unconfirmed = bus.tx_unconfirmed;
            s.can_tx_waits = bus.tx_confirm_waits;
            s.can_bus_off = bus.bus_off;
            s.can_error_passive = bus.error_passive;
        }
        s.bus_errors = get(a.bus_errors);
        s.heartbeat_errors = get(a.heartbeat_errors);
        s.heartbeat_misses = get(a.heartbeat_misses);
        s.rx_tool_fired = get(a.rx_tool_fired);
        s.fired_unmatched = get(a.fired_unmatched);
        s.compensation_misses = get(a.compensation_misses);
        for (const ToolTimingCounters& c : a.tool_timing) {
            if (!c.configured.load(std::memory_order_acquire) || s.n_tools >= s.tool_timing.size())
                break;
            StatusSnapshot::ToolTiming& t = s.tool_timing[s.n_tools++];
            t.tool_id = c.tool_id.load(std::memory_order_relaxed);
            t.learning = c.learning.load(std::memory_order_relaxed);
            t.latency_ms = c.latency_ms.load(std::memory_order_relaxed);
            t.fired = get(c.fired);
            t.lag_mean_mm = c.lag_mean_mm.load(std::memory_order_relaxed);
            t.lag_p95_mm = c.lag_p95_mm.load(std::memory_order_relaxed);
            t.lag_mean_ms = c.lag_mean_ms.load(std::memory_order_relaxed);
            t.lag_p95_ms = c.lag_p95_ms.load(std::memory_order_relaxed);
            t.strike_p95_mm = c.strike_p95_mm.load(std::memory_order_relaxed);
        }
        if (const GnssInput* g = actuation_->gnss()) {
            const GnssCountersView v = g->counters();
            s.gnss = true;
            s.gnss_mode = v.last.mode;
            s.gnss_status = v.last.status;
            s.gnss_eph_mm = v.last.eph_mm;
            s.gnss_max_eph_mm = g->max_eph_mm();
            s.gnss_fixes = v.fixes;
            s.gnss_degraded = v.degraded;
        }
        DurationHistogram& send = actuation_->counters().send_latency;
        s.send = whole_run ? send.total() : send.take_interval();
    }
    s.latency = whole_run ? counters_->actuator.latency.total() : counters_->actuator.latency.take_interval();
    s.pipeline = whole_run ? counters_->processing.pipeline.total() : counters_->processing.pipeline.take_interval();
    return s;
}

}  // namespace stemd::runtime
