#include "stemd/runtime/actuation_stage.hpp"

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
        error = "can.base_id " + std::to_string(config.can_base_id) + " leaves no room for the four identifiers";
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
                                                              scheduler_all, *ids, std::move(log)));
}

ActuationStage::ActuationStage(const ActuationConfig& config, Parts parts, PlantProjector projector,
                               actuation::Scheduler scheduler, std::optional<actuation::Scheduler> scheduler_all,
                               protocol::CanIds ids, std::shared_ptr<spdlog::logger> log)
    : config_(config),
      parts_(std::move(parts)),
      log_(std::move(log)),
      odometry_(config, counters_),
      projector_(projector),
      tracker_(config.tracker),
      sender_(scheduler, scheduler_all, *parts_.bus, ids, odometry_, counters_),
      link_(*parts_.bus, ids, config.heartbeat_interval_ns, odometry_, counters_)
{
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
    if (!odometry_.odometer_at(r.t_sample_ns, odom_at_capture)) {
        bump(counters_.no_odometry);
        return;
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
    for (const actuation::Target& t : targets) {
        bump(counters_.targets);
        if (sender_.schedule(t, now_ns, r.has_class_map, enabled()))
            counters_.send_latency.record(now_ns - r.t_sample_ns);
    }
    write_retired(tracker_.retired());
}

void ActuationStage::write_retired(std::span<const actuation::RetiredTrack> retired) noexcept
{
    if (!parts_.map && live_feed_ == nullptr)
        return;
    for (const actuation::RetiredTrack& t : retired) {
        MapEntry entry;
        if (t.emitted)
            entry = sender_.outcome(t.target_id);
        else
            entry.reason = MapReason::unconfirmed;
        if (parts_.map && !parts_.map->write(t, entry))
            bump(counters_.map_errors);
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
    }
}

void ActuationStage::poll(std::int64_t now_ns) noexcept
{
    link_.receive();
    if (config_.odometry == OdometrySource::encoder)
        odometry_.add_encoder(now_ns, parts_.gpio->encoder().ticks);
    link_.heartbeat_if_due(now_ns, last_frame_ns_ >= 0, enabled());
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
    if (!parts_.map)
        return ok;
    write_retired(tracker_.drain());
    ok = parts_.map->close() && counters_.map_errors.load(std::memory_order_relaxed) == 0 && ok;
    parts_.map.reset();
    return ok;
}

}  // namespace stemd::runtime
