#include "stemd/runtime/actuation_stage.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "stemd/geometry/field.hpp"
#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

namespace {

using actuation::PlantClass;

// Speed over this window: smooths encoder ticks and frame-rate odometry.
constexpr std::int64_t kSpeedWindowNs = 200'000'000;

// The along-track extent of the view relative to the odometer at capture:
// the image border's field positions (corners and edge midpoints, enough
// for the nadir model and for mild tilt/distortion).
bool view_extent(const geometry::CameraModel& camera, cv::Size size, double& lo, double& hi)
{
    const double w = size.width - 1, h = size.height - 1;
    const cv::Point2f border[] = {{0, 0}, {static_cast<float>(w / 2), 0}, {static_cast<float>(w), 0},
                                  {0, static_cast<float>(h / 2)}, {static_cast<float>(w), static_cast<float>(h / 2)},
                                  {0, static_cast<float>(h)}, {static_cast<float>(w / 2), static_cast<float>(h)},
                                  {static_cast<float>(w), static_cast<float>(h)}};
    lo = std::numeric_limits<double>::infinity();
    hi = -lo;
    for (const cv::Point2f& px : border)
        if (const auto p = geometry::field_position(camera, px, 0.0)) {
            lo = std::min(lo, p->s_mm);
            hi = std::max(hi, p->s_mm);
        }
    return lo <= hi;
}

actuation::SchedulerParams with_policy(actuation::SchedulerParams p, actuation::TreatPolicy policy)
{
    p.policy = policy;
    return p;
}

MapReason reason_of(actuation::ScheduleOutcome o)
{
    using actuation::ScheduleOutcome;
    switch (o) {
    case ScheduleOutcome::send: return MapReason::sent;
    case ScheduleOutcome::policy: return MapReason::policy;
    case ScheduleOutcome::no_tool: return MapReason::no_tool;
    case ScheduleOutcome::disabled: return MapReason::disabled;
    case ScheduleOutcome::deadline_miss: return MapReason::deadline_miss;
    }
    return MapReason::pending;
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
    const auto ids = actuation::CanIds::make(config.can_base_id);
    if (!ids) {
        error = "can.base_id " + std::to_string(config.can_base_id) + " leaves no room for the four identifiers";
        return nullptr;
    }
    std::unique_ptr<ActuationStage> stage(
        new ActuationStage(config, camera, frame_size, std::move(parts), *scheduler, *ids, std::move(log)));
    if (!view_extent(camera, frame_size, stage->view_min_mm_, stage->view_max_mm_)) {
        error = "the camera model puts no part of the image on the ground";
        return nullptr;
    }
    if (config.policy == PolicyChoice::automatic)
        stage->scheduler_all_ =
            actuation::Scheduler::make(config.tools, with_policy(config.scheduler, actuation::TreatPolicy::all));
    return stage;
}

ActuationStage::ActuationStage(const ActuationConfig& config, const geometry::CameraModel& camera,
                               cv::Size frame_size, Parts parts,
                               actuation::Scheduler scheduler, actuation::CanIds ids,
                               std::shared_ptr<spdlog::logger> log)
    : config_(config),
      camera_(camera),
      frame_size_(frame_size),
      parts_(std::move(parts)),
      log_(std::move(log)),
      tracker_(config.tracker),
      scheduler_(scheduler),
      ids_(ids),
      odometry_({.capacity = 1024, .max_extrapolation_ns = config.max_extrapolation_ns}),
      odometry_checker_(ids.id(actuation::MessageKind::Odometry), 3),
      tool_status_checker_(ids.id(actuation::MessageKind::ToolStatus), 3)
{
}

ActuationStage::~ActuationStage()
{
    finish();
}

bool ActuationStage::odometer_at(std::int64_t t_ns, double& odom_mm) const noexcept
{
    if (constant_now_) {
        // A constant speed is known at every instant: it never goes stale.
        odom_mm = geometry::ConstantSpeedOdometer(config_.speed_mm_per_s, constant_t0_ns_).sample(t_ns).odom_mm;
        return true;
    }
    const geometry::OdomQuery q = odometry_.odom_at(t_ns);
    if (q.status != geometry::OdomStatus::ok && q.status != geometry::OdomStatus::extrapolated)
        return false;
    odom_mm = q.odom_mm;
    return true;
}

void ActuationStage::on_capture(std::int64_t t_capture_ns, double odom_mm) noexcept
{
    add_frame_odometry(t_capture_ns, odom_mm);
}

void ActuationStage::add_frame_odometry(std::int64_t t_capture_ns, double odom_mm) noexcept
{
    const bool frame_has_odom = std::isfinite(odom_mm);
    geometry::OdomSample sample{t_capture_ns, 0};
    constant_now_ = false;
    switch (config_.odometry) {
    case OdometrySource::recording:
        if (!frame_has_odom)
            return;
        sample.odom_mm = odom_mm;
        break;
    case OdometrySource::automatic:
        if (frame_has_odom) {
            sample.odom_mm = odom_mm;
            break;
        }
        [[fallthrough]];
    case OdometrySource::constant:
        if (constant_t0_ns_ < 0)
            constant_t0_ns_ = t_capture_ns;
        constant_now_ = true;
        sample = geometry::ConstantSpeedOdometer(config_.speed_mm_per_s, constant_t0_ns_).sample(t_capture_ns);
        break;
    case OdometrySource::encoder:
    case OdometrySource::can:
        // Sampled in poll() with the time they were read; a reading taken
        // now is not the odometer at this frame's capture.
        return;
    }
    if (!odometry_.empty() && odometry_.newest().t_ns >= sample.t_ns)
        return;   // the same instant again (no new information)
    if (!odometry_.push(sample))
        bump(counters_.odometry_rejected);
}

void ActuationStage::on_frame(const FrameResult& r, std::int64_t now_ns) noexcept
{
    last_frame_ns_ = now_ns;
    add_frame_odometry(r.t_capture_ns, r.odom_mm);
    double odom_at_capture = 0;
    if (!odometer_at(r.t_capture_ns, odom_at_capture)) {
        bump(counters_.no_odometry);
        return;
    }
    std::size_t n = 0;
    const auto& plants = r.detections.plants;
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const vision::Plant& p = plants[i];
        if (!p.has_stem)
            continue;
        if (clipped_along_track(p.bbox)) {
            bump(counters_.clipped);
            continue;
        }
        const auto field = geometry::field_position(camera_, p.stem, odom_at_capture);
        if (!field) {
            bump(counters_.off_ground);
            continue;
        }
        actuation::TrackDetection& d = detections_[n++];
        d.s_mm = field->s_mm;
        d.y_mm = field->y_mm;
        d.confidence = p.confidence;
        d.plant_class = r.has_class_map && r.plant_class[i] <= 2 ? static_cast<PlantClass>(r.plant_class[i])
                                                                : PlantClass::Unknown;
        d.leaves = static_cast<std::uint8_t>(std::min<std::size_t>(p.leaves.size(), 255));
        d.extent_mm = extent_mm(p, odom_at_capture);
    }
    actuation::TrackFrame frame;
    frame.seq = r.seq;
    frame.t_capture_ns = r.t_capture_ns;
    frame.odom_at_capture_mm = odom_at_capture;
    frame.view_s_min_mm = odom_at_capture + view_min_mm_;
    frame.view_s_max_mm = odom_at_capture + view_max_mm_;
    frame.detections = {detections_.data(), n};
    const std::span<const actuation::Target> targets = tracker_.update(frame);
    bump(counters_.frames);
    for (const actuation::Target& t : targets) {
        bump(counters_.targets);
        schedule(t, now_ns, r.has_class_map);
    }
    write_retired(tracker_.retired());
}

bool ActuationStage::clipped_along_track(const cv::Rect& bbox) const noexcept
{
    using geometry::Forward;
    const Forward f = camera_.mount().forward;
    if (f == Forward::up || f == Forward::down)
        return bbox.y <= 0 || bbox.y + bbox.height >= frame_size_.height;
    return bbox.x <= 0 || bbox.x + bbox.width >= frame_size_.width;
}

double ActuationStage::extent_mm(const vision::Plant& p, double odom_mm) const noexcept
{
    // Half the distance along track between the plant's two along-track
    // bounding-box edges, through the stem.
    using geometry::Forward;
    const Forward f = camera_.mount().forward;
    const bool vertical = f == Forward::up || f == Forward::down;
    const cv::Point2f a = vertical ? cv::Point2f(p.stem.x, static_cast<float>(p.bbox.y))
                                   : cv::Point2f(static_cast<float>(p.bbox.x), p.stem.y);
    const cv::Point2f b = vertical ? cv::Point2f(p.stem.x, static_cast<float>(p.bbox.y + p.bbox.height - 1))
                                   : cv::Point2f(static_cast<float>(p.bbox.x + p.bbox.width - 1), p.stem.y);
    const auto fa = geometry::field_position(camera_, a, odom_mm);
    const auto fb = geometry::field_position(camera_, b, odom_mm);
    return fa && fb ? std::abs(fa->s_mm - fb->s_mm) / 2 : 0.0;
}

void ActuationStage::schedule(const actuation::Target& target, std::int64_t now_ns, bool class_map) noexcept
{
    MapEntry& entry = outcomes_[target.target_id];
    entry = MapEntry{};
    // The odometer and speed now (not at capture): the time the pipeline
    // took is already gone from the command's budget.
    double odom_now = 0;
    if (!odometer_at(now_ns, odom_now)) {
        entry.reason = MapReason::no_odometry;
        bump(counters_.no_odometry);
        return;
    }
    actuation::ScheduleNow now;
    now.now_ns = now_ns;
    now.odom_mm = odom_now;
    now.speed_mm_per_s = constant_now_ ? config_.speed_mm_per_s : odometry_.speed_mm_per_s(kSpeedWindowNs);
    now.enabled = parts_.gpio ? parts_.gpio->enabled() : true;
    actuation::Scheduler& scheduler = (scheduler_all_ && !class_map) ? *scheduler_all_ : scheduler_;
    const actuation::ScheduleDecision d = scheduler.schedule(target, now);
    entry.reason = reason_of(d.outcome);
    if (d.outcome != actuation::ScheduleOutcome::policy && d.outcome != actuation::ScheduleOutcome::no_tool) {
        entry.has_tool = true;
        entry.tool = d.command.tool_id;
        entry.lane = d.command.lane;
        entry.fire_odom_mm = d.fire_odom_mm;
    }
    switch (d.outcome) {
    case actuation::ScheduleOutcome::policy: bump(counters_.policy); return;
    case actuation::ScheduleOutcome::no_tool: bump(counters_.no_tool); return;
    case actuation::ScheduleOutcome::disabled: bump(counters_.disabled); return;
    case actuation::ScheduleOutcome::deadline_miss: bump(counters_.deadline_misses); return;
    case actuation::ScheduleOutcome::send: break;
    }
    actuation::CanFrame frame;
    if (!actuation::encode(d.command, target_counter_.next(), ids_, frame)) {
        // The scheduler keeps every field in range; count it if not.
        entry.reason = MapReason::bus_error;
        bump(counters_.bus_errors);
        return;
    }
    switch (parts_.bus->send(frame, d.deadline_ns)) {
    case drivers::SendResult::sent: bump(counters_.sent); break;
    case drivers::SendResult::deadline_passed:
        entry.reason = MapReason::bus_deadline;
        bump(counters_.bus_deadline);
        break;
    case drivers::SendResult::error:
        entry.reason = MapReason::bus_error;
        bump(counters_.bus_errors);
        break;
    }
}

void ActuationStage::write_retired(std::span<const actuation::RetiredTrack> retired) noexcept
{
    if (!parts_.map)
        return;
    for (const actuation::RetiredTrack& t : retired) {
        MapEntry entry;
        if (t.emitted)
            entry = outcomes_[t.target_id];
        else
            entry.reason = MapReason::unconfirmed;
        if (!parts_.map->write(t, entry))
            bump(counters_.map_errors);
    }
}

void ActuationStage::poll(std::int64_t now_ns) noexcept
{
    receive(now_ns);
    if (config_.odometry == OdometrySource::encoder) {
        const geometry::OdomSample sample{
            now_ns, static_cast<double>(parts_.gpio->encoder().ticks) * config_.encoder_mm_per_tick};
        // A sample per ~2 ms is plenty for interpolation and speed.
        if (odometry_.empty() || now_ns - odometry_.newest().t_ns >= 2'000'000)
            if (!odometry_.push(sample))
                bump(counters_.odometry_rejected);
    }
    if (now_ns >= next_heartbeat_ns_)
        heartbeat(now_ns);
}

void ActuationStage::receive(std::int64_t now_ns) noexcept
{
    actuation::CanFrame frame;
    // Whatever is queued, without waiting; bounded so a flooded bus cannot
    // starve the frames.
    for (int i = 0; i < 64 && parts_.bus->receive(frame, 0); ++i) {
        const auto kind = ids_.kind_of(frame);
        if (!kind)
            continue;   // not one of ours (the socket filter normally keeps these out)
        const std::span<const std::uint8_t, 8> data(frame.data.data(), 8);
        if (*kind == actuation::MessageKind::Odometry) {
            actuation::Odometry m;
            if (frame.dlc != 8 || !actuation::e2e_accepted(odometry_checker_.check(data)) ||
                !actuation::decode(frame, ids_, m)) {
                bump(counters_.rx_rejected);
                continue;
            }
            bump(counters_.rx_odometry);
            if (config_.odometry != OdometrySource::can)
                continue;
            // Unwrap the 32-bit odometer.
            if (!have_odometry_frame_) {
                can_odom_mm_ = m.odom_mm;
                have_odometry_frame_ = true;
            } else {
                can_odom_mm_ += static_cast<double>(static_cast<std::int32_t>(m.odom_mm - last_can_odom_raw_));
            }
            last_can_odom_raw_ = m.odom_mm;
            if (!odometry_.push({now_ns, can_odom_mm_}))
                bump(counters_.odometry_rejected);
        } else if (*kind == actuation::MessageKind::ToolStatus) {
            actuation::ToolStatus m;
            if (frame.dlc != 8 || !actuation::e2e_accepted(tool_status_checker_.check(data)) ||
                !actuation::decode(frame, ids_, m)) {
                bump(counters_.rx_rejected);
                continue;
            }
            bump(counters_.rx_tool_status);
            counters_.tools_ready_mask.store(m.tools_ready_mask, std::memory_order_relaxed);
        }
    }
}

void ActuationStage::heartbeat(std::int64_t now_ns) noexcept
{
    // On a fixed grid (10 Hz stays 10 Hz however late a poll comes); a
    // heartbeat more than a period late is not caught up.
    next_heartbeat_ns_ = next_heartbeat_ns_ == 0 || now_ns - next_heartbeat_ns_ >= config_.heartbeat_interval_ns
        ? now_ns + config_.heartbeat_interval_ns
        : next_heartbeat_ns_ + config_.heartbeat_interval_ns;
    const std::uint64_t misses = counters_.deadline_misses.load(std::memory_order_relaxed) +
                                 counters_.bus_deadline.load(std::memory_order_relaxed);
    actuation::Heartbeat hb;
    double odom = 0;
    const bool enabled = parts_.gpio ? parts_.gpio->enabled() : true;
    if (last_frame_ns_ < 0)
        hb.state = actuation::DaemonState::Starting;
    else if (!enabled || !odometer_at(now_ns, odom))
        hb.state = actuation::DaemonState::Idle;
    else if (misses != misses_at_last_heartbeat_)
        hb.state = actuation::DaemonState::Degraded;
    else
        hb.state = actuation::DaemonState::Active;
    misses_at_last_heartbeat_ = misses;
    hb.targets_sent = counters_.sent.load(std::memory_order_relaxed);
    hb.deadline_misses = misses;
    hb.targets_dropped = counters_.no_tool.load(std::memory_order_relaxed) +
                         counters_.disabled.load(std::memory_order_relaxed) +
                         counters_.bus_errors.load(std::memory_order_relaxed);
    hb.rx_rejected = counters_.rx_rejected.load(std::memory_order_relaxed);
    actuation::CanFrame frame;
    // Heartbeat failures have their own counter: bus_errors goes out inside
    // targets_dropped and must count TARGETs only.
    if (!actuation::encode(hb, heartbeat_counter_.next(), ids_, frame)) {
        bump(counters_.heartbeat_errors);
        return;
    }
    if (parts_.bus->send(frame, now_ns + config_.heartbeat_interval_ns) == drivers::SendResult::sent)
        bump(counters_.heartbeats);
    else
        bump(counters_.heartbeat_errors);
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
