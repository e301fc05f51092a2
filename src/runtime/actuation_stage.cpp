#include "stemd/runtime/actuation_stage.hpp"

#include <time.h>

#include "stemd/base/clock.hpp"
#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

namespace {

actuation::SchedulerParams with_policy(actuation::SchedulerParams p, actuation::TreatPolicy policy)
{
    p.policy = policy;
    return p;
}

}  // namespace

std::unique_ptr<ActuationStage> ActuationStage::make(const ActuationConfig& config,
                                                     const geometry::CameraModel& camera, cv::Size frame_size,
                                                     Parts parts, std::shared_ptr<spdlog::logger> log,
                                                     std::string& error)
{
    if (!parts.bus) {
        error = "no CAN bus";
        return nullptr;
    }
    if (config.odometry == OdometrySource::encoder &&
        (!parts.gpio || parts.gpio->encoder_mode() == drivers::EncoderMode::none)) {
        error = "odometry.source is encoder but no encoder is configured (gpio.chip, gpio.encoder, gpio.encoder_a_line)";
        return nullptr;
    }
    const actuation::TreatPolicy policy =
        config.policy == PolicyChoice::all ? actuation::TreatPolicy::all : actuation::TreatPolicy::weeds_only;
    std::string_view why;
    auto scheduler = actuation::Scheduler::make(config.tools, with_policy(config.scheduler, policy), &why);
    if (!scheduler) {
        error = "tools / scheduler: " + std::string(why);
        return nullptr;
    }
    const auto ids = protocol::CanIds::make(config.can_base_id);
    if (!ids) {
        error = "can.base_id " + std::to_string(config.can_base_id) + " leaves no room for the five identifiers";
        return nullptr;
    }
    auto projector = PlantProjector::make(camera, frame_size);
    if (!projector) {
        error = "the camera model puts no part of the image on the ground";
        return nullptr;
    }
    std::optional<actuation::Scheduler> scheduler_all;
    if (config.policy == PolicyChoice::automatic)
        scheduler_all =
            actuation::Scheduler::make(config.tools, with_policy(config.scheduler, actuation::TreatPolicy::all));
    return std::unique_ptr<ActuationStage>(new ActuationStage(config, std::move(parts), *projector, *scheduler,
                                                              scheduler_all, *ids, std::move(log),
                                                              camera.mount().x_mm));
}

ActuationStage::ActuationStage(const ActuationConfig& config, Parts parts, PlantProjector projector,
                               actuation::Scheduler scheduler, std::optional<actuation::Scheduler> scheduler_all,
                               protocol::CanIds ids, std::shared_ptr<spdlog::logger> log, double principal_x_mm)
    : config_(config),
      parts_(std::move(parts)),
      log_(std::move(log)),
      odometry_(config, counters_),
      projector_(projector),
      tracker_(config.tracker),
      sender_(scheduler, scheduler_all, *parts_.bus, ids, odometry_, counters_, config.tool_status_timeout_ns),
      link_(*parts_.bus, ids, config.heartbeat_interval_ns, odometry_, sender_, counters_)
{
    if (parts_.gnss)
        gnss_.emplace(config.gnss, principal_x_mm);
}

void ActuationStage::poll_gnss(std::int64_t now_ns) noexcept
{
    if (!gnss_)
        return;
    // The clocks' offset now, for fixes placed by their own (UTC) time.
    timespec rt{};
    clock_gettime(CLOCK_REALTIME, &rt);
    const std::int64_t realtime_ns = static_cast<std::int64_t>(rt.tv_sec) * 1'000'000'000 + rt.tv_nsec;
    gnss_->poll(*parts_.gnss, odometry_, now_ns, realtime_ns - base::monotonic_ns());
}

ActuationStage::~ActuationStage()
{
    finish();
}

void ActuationStage::on_capture(std::int64_t t_sample_ns, double odom_mm) noexcept
{
    odometry_.add_frame(t_sample_ns, odom_mm);
}

void ActuationStage::on_frame(const FrameResult& r, std::int64_t now_ns) noexcept
{
    last_frame_ns_ = now_ns;
    odometry_.add_frame(r.t_sample_ns, r.odom_mm);
    double odom_at_capture = 0;
    if (!odometry_.frame_odometer(r.t_sample_ns, r.odom_mm, odom_at_capture)) {
        bump(counters_.no_odometry);
        return;
    }
    if (!odometry_announced_) {
        // Once: where the odometer starts on CLOCK_MONOTONIC (what a GNSS
        // log or another recorder is lined up with).
        odometry_announced_ = true;
        log_->info("odometry: first frame captured at t_ns {} (CLOCK_MONOTONIC), odometer {:.1f} mm, {:.1f} mm/s",
                   r.t_sample_ns, odom_at_capture, odometry_.speed_mm_per_s());
    }
    actuation::TrackFrame frame;
    frame.seq = r.seq;
    frame.t_sample_ns = r.t_sample_ns;
    frame.odom_at_capture_mm = odom_at_capture;
    frame.view_s_min_mm = odom_at_capture + projector_.view_forward_min_mm();
    frame.view_s_max_mm = odom_at_capture + projector_.view_forward_max_mm();
    frame.detections = projector_.project(r, odom_at_capture, counters_);
    const std::span<const actuation::Target> targets = tracker_.update(frame);
    bump(counters_.frames);
    ++frames_tracked_;
    last_seq_ = r.seq;
    last_capture_ns_ = r.t_sample_ns;
    prev_odom_mm_ = last_odom_mm_;
    last_odom_mm_ = odom_at_capture;
    last_class_map_ = r.has_class_map;
    for (const actuation::Target& t : targets) {
        bump(counters_.targets);
        if (sender_.schedule(t, now_ns, r.has_class_map, enable_gate()))
            counters_.send_latency.record(now_ns - r.t_sample_ns);
        if (live_feed_ != nullptr)
            live_feed_->push_target(
                {.target_id = t.target_id,
                 .s_mm = t.s_mm,
                 .y_mm = t.y_mm,
                 .reason = sender_.outcome(t.target_id).reason,
                 .t_sample_ns = r.t_sample_ns,
                 .odom_at_capture_mm = odom_at_capture,
                 .speed_mm_per_s = odometry_.speed_mm_per_s()});
    }
    poll_gnss(now_ns);
    write_retired(tracker_.retired(), now_ns);
}

void ActuationStage::write_retired(std::span<const actuation::RetiredTrack> retired, std::int64_t now_ns) noexcept
{
    if (!parts_.map && live_feed_ == nullptr)
        return;
    for (const actuation::RetiredTrack& t : retired) {
        MapEntry entry;
        if (t.emitted)
            entry = sender_.outcome(t.target_id);
        else
            entry.reason = MapReason::unconfirmed;
        if (live_feed_ != nullptr)
            live_feed_->push_plant({.id = t.emitted ? static_cast<std::int32_t>(t.target_id) : -1,
                                    .s_mm = t.s_mm,
                                    .y_mm = t.y_mm,
                                    .plant_class = t.plant_class,
                                    .leaves = t.leaves,
                                    .sightings = t.sightings,
                                    .first_frame = t.first_seq,
                                    .last_frame = t.last_seq,
                                    .entry = entry});
        if (!parts_.map)
            continue;
        // A tool that reports its strikes: the line waits for this one's.
        if (entry.reason == MapReason::sent && !entry.fired && sender_.reports_fired(entry.tool) &&
            n_waiting_ < waiting_.size()) {
            for (Waiting& w : waiting_)
                if (!w.used) {
                    w = Waiting{true, t, entry};
                    ++n_waiting_;
                    break;
                }
            continue;
        }
        write_line(t, entry, now_ns);
    }
}

void ActuationStage::write_line(const actuation::RetiredTrack& track, const MapEntry& entry,
                                std::int64_t now_ns) noexcept
{
    MapEntry placed = entry;
    if (gnss_)
        placed.georef = gnss_->place(track.s_mm, track.y_mm, now_ns);
    if (!parts_.map->write(track, placed))
        bump(counters_.map_errors);
}

void ActuationStage::write_waiting(std::int64_t now_ns, bool all) noexcept
{
    if (!parts_.map || n_waiting_ == 0)
        return;
    double odom = 0;
    const bool have_odom = odometry_.odometer_at(now_ns, odom);
    for (Waiting& w : waiting_) {
        if (!w.used)
            continue;
        const MapEntry& now = sender_.outcome(w.track.target_id);
        // Still this plant's outcome (target ids wrap at 4096)?
        const bool same = now.reason == MapReason::sent && now.tool == w.entry.tool &&
                          now.aim_odom_mm == w.entry.aim_odom_mm;
        const bool gave_up = have_odom && odom > w.entry.fire_odom_mm + kFiredWaitMm;
        if (!all && same && !now.fired && !gave_up)
            continue;
        write_line(w.track, same ? now : w.entry, now_ns);
        w.used = false;
        --n_waiting_;
    }
}

void ActuationStage::poll(std::int64_t now_ns, bool camera_lost) noexcept
{
    link_.receive();
    if (config_.odometry == OdometrySource::encoder)
        odometry_.add_encoder(now_ns, parts_.gpio->encoder().ticks);
    enable_input_seen_.store(enable_input(), std::memory_order_relaxed);
    link_.heartbeat_if_due(now_ns, last_frame_ns_ >= 0, camera_lost, enabled());
    poll_gnss(now_ns);
    write_waiting(now_ns, false);
}

void ActuationStage::end_of_stream() noexcept
{
    const double step_mm = last_odom_mm_ - prev_odom_mm_;
    if (frames_tracked_ < 2 || !(step_mm > 0))
        return;
    actuation::TrackFrame frame;
    frame.seq = last_seq_ + 1;
    frame.t_sample_ns = last_capture_ns_;
    frame.odom_at_capture_mm = last_odom_mm_ + step_mm;
    frame.view_s_min_mm = frame.odom_at_capture_mm + projector_.view_forward_min_mm();
    frame.view_s_max_mm = frame.odom_at_capture_mm + projector_.view_forward_max_mm();
    for (const actuation::Target& t : tracker_.update(frame)) {
        bump(counters_.targets);
        sender_.schedule(t, last_capture_ns_, last_class_map_, enable_gate());
    }
    write_retired(tracker_.retired(), base::monotonic_ns());
}

bool ActuationStage::finish() noexcept
{
    bool ok = true;
    if (parts_.bus && parts_.bus->output_lost() && !bus_loss_reported_) {
        const drivers::CanBusCounters c = parts_.bus->counters();
        log_->error("{}: {} frames could not be written (sent {}); the CAN log is incomplete", parts_.bus->name(),
                    c.errors, c.sent);
        bus_loss_reported_ = true;
        ok = false;
    }
    if (gnss_ && !gnss_reported_) {
        gnss_reported_ = true;
        const std::int64_t now_ns = base::monotonic_ns();
        poll_gnss(now_ns);
        const GnssCountersView g = gnss_->counters();
        const drivers::GnssCounters d = parts_.gnss->counters();
        log_->info("{}: {} fixes ({} without a position, {} dropped), {} on the track, {} without an odometer "
                   "reading; {} connections, {} failures; {} plants degraded (eph over {:.0f} mm)",
                   parts_.gnss->name(), g.fixes, d.no_fix, d.dropped, g.on_track, g.unplaced, d.connects,
                   d.failures, g.degraded, gnss_->max_eph_mm());
    }
    if (!parts_.map)
        return ok;
    const std::int64_t end_ns = base::monotonic_ns();
    write_retired(tracker_.drain(), end_ns);
    write_waiting(end_ns, true);
    ok = parts_.map->close() && counters_.map_errors.load(std::memory_order_relaxed) == 0 && ok;
    if (parts_.map->output_stalled())
        static_cast<void>(parts_.map.release());   // the writer may still be in its file: leaked, the process ends
    else
        parts_.map.reset();
    return ok;
}

}  // namespace stemd::runtime
