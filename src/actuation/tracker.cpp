#include "stemd/actuation/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace stemd::actuation {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

TrackerParams sanitise(TrackerParams p)
{
    if (!(p.association_radius_mm > 0) || !std::isfinite(p.association_radius_mm))
        p.association_radius_mm = TrackerParams{}.association_radius_mm;
    if (!(p.exit_margin_mm >= 0) || !std::isfinite(p.exit_margin_mm))
        p.exit_margin_mm = 0;
    p.confirm_frames = std::max<std::uint32_t>(p.confirm_frames, 1);
    p.max_missed_frames = std::max<std::uint32_t>(p.max_missed_frames, 1);
    // Track indices and detection indices are stored as uint32.
    p.capacity = std::clamp<std::size_t>(p.capacity, 1, 1u << 16);
    p.max_detections = std::clamp<std::size_t>(p.max_detections, 1, 1u << 16);
    return p;
}

// What a track knows of its plant, as a Target and a RetiredTrack both
// report it.
template <typename TrackT, typename Out>
void describe_plant(const TrackT& t, Out& out) noexcept
{
    out.s_mm = t.s_mm;
    out.y_mm = t.y_mm;
    out.plant_class = t.plant_class();
    out.sightings = t.sightings;
    out.leaves = t.leaves;
    out.confidence = t.mean_confidence();
    out.first_seq = t.first_seq;
}

}  // namespace

Tracker::Tracker(const TrackerParams& params)
    : params_(sanitise(params)),
      tracks_(std::make_unique<Track[]>(params_.capacity)),
      candidates_(std::make_unique<Candidate[]>(params_.capacity * params_.max_detections)),
      det_track_(std::make_unique<std::uint32_t[]>(params_.max_detections)),
      out_(std::make_unique<Target[]>(params_.capacity)),
      retired_(std::make_unique<RetiredTrack[]>(params_.capacity))
{
}

void Tracker::reset() noexcept
{
    for (std::size_t i = 0; i < params_.capacity; ++i)
        tracks_[i] = Track{};
    active_ = 0;
    n_out_ = 0;
    n_retired_ = 0;
}

void Tracker::add_sighting(Track& t, const TrackDetection& d, std::uint64_t seq) noexcept
{
    if (t.sightings == 0)
        t.first_seq = seq;
    t.last_seq = seq;
    const double c = std::isfinite(d.confidence) ? static_cast<double>(d.confidence) : 0.0;
    const double w = std::max(c, kMinWeight);
    t.w_sum += w;
    t.ws_sum += w * d.s_mm;
    t.wy_sum += w * d.y_mm;
    t.s_mm = t.ws_sum / t.w_sum;
    t.y_mm = t.wy_sum / t.w_sum;
    if (d.plant_class == PlantClass::Crop)
        t.crop_w += w;
    else if (d.plant_class == PlantClass::Weed)
        t.weed_w += w;
    t.conf_sum += c;
    t.leaves = std::max(t.leaves, d.leaves);
    if (std::isfinite(d.extent_mm))
        t.extent_mm = std::max(t.extent_mm, d.extent_mm);
    ++t.sightings;
    t.missed = 0;
    t.seen_this_frame = true;
}

void Tracker::emit(Track& t, const TrackFrame& frame, bool by_exit) noexcept
{
    // At most one emission per track per frame, and at most `capacity`
    // tracks: out_ never overflows.
    Target& o = out_[n_out_++];
    o.target_id = static_cast<std::uint16_t>(next_id_ % (protocol::kMaxTargetId + 1u));
    next_id_ = (next_id_ + 1) % (protocol::kMaxTargetId + 1u);
    describe_plant(t, o);
    o.by_exit = by_exit;
    o.t_emit_ns = frame.t_sample_ns;
    t.target_id = o.target_id;
    t.emitted = true;
    ++counters_.confirmed;
    if (by_exit)
        ++counters_.confirmed_by_exit;
}

void Tracker::retire(std::size_t i) noexcept
{
    Track& t = tracks_[i];
    ++counters_.retired;
    if (!t.emitted)
        ++counters_.retired_unconfirmed;
    // At most `capacity` tracks retire per update() or drain().
    RetiredTrack& r = retired_[n_retired_++];
    r.emitted = t.emitted;
    r.target_id = t.target_id;
    describe_plant(t, r);
    r.last_seq = t.last_seq;
    t = Track{};
    --active_;
}

std::span<const Target> Tracker::update(const TrackFrame& frame) noexcept
{
    ++counters_.frames;
    n_out_ = 0;
    n_retired_ = 0;
    const std::size_t cap = params_.capacity;

    std::size_t n_det = frame.detections.size();
    if (n_det > params_.max_detections) {
        counters_.detections_dropped += n_det - params_.max_detections;
        n_det = params_.max_detections;
    }
    const TrackDetection* dets = frame.detections.data();

    for (std::size_t i = 0; i < cap; ++i)
        tracks_[i].seen_this_frame = false;

    // 1. Candidate pairs, closest first, one-to-one.
    const double r = params_.association_radius_mm;
    const double r2 = r * r;
    std::size_t n_cand = 0;
    for (std::size_t d = 0; d < n_det; ++d) {
        det_track_[d] = kNone;
        if (!std::isfinite(dets[d].s_mm) || !std::isfinite(dets[d].y_mm))
            continue;
        for (std::size_t i = 0; i < cap; ++i) {
            const Track& t = tracks_[i];
            if (!t.active || t.weed_part != dets[d].weed_part)
                continue;
            const double ds = dets[d].s_mm - t.s_mm;
            if (ds >= r || ds <= -r)
                continue;
            const double dy = dets[d].y_mm - t.y_mm;
            const double d2 = ds * ds + dy * dy;
            if (d2 < r2)
                candidates_[n_cand++] = {d2, static_cast<std::uint32_t>(d), static_cast<std::uint32_t>(i)};
        }
    }
    // Ties broken by detection, then track index: deterministic.
    std::sort(candidates_.get(), candidates_.get() + n_cand, [](const Candidate& a, const Candidate& b) {
        if (a.d2 != b.d2)
            return a.d2 < b.d2;
        if (a.det != b.det)
            return a.det < b.det;
        return a.track < b.track;
    });
    for (std::size_t k = 0; k < n_cand; ++k) {
        const Candidate& c = candidates_[k];
        if (det_track_[c.det] != kNone || tracks_[c.track].seen_this_frame)
            continue;
        det_track_[c.det] = c.track;
        tracks_[c.track].seen_this_frame = true;
    }

    // 2. Fusion (after the assignment, so that it used this frame's
    //    positions of the tracks before any update).
    std::size_t free_hint = 0;
    for (std::size_t d = 0; d < n_det; ++d) {
        const TrackDetection& det = dets[d];
        if (!std::isfinite(det.s_mm) || !std::isfinite(det.y_mm)) {
            ++counters_.rejected_detections;
            continue;
        }
        if (det_track_[d] != kNone) {
            add_sighting(tracks_[det_track_[d]], det, frame.seq);
            continue;
        }
        // 3. A new track.
        while (free_hint < cap && tracks_[free_hint].active)
            ++free_hint;
        if (free_hint == cap) {
            ++counters_.capacity_drops;
            continue;
        }
        Track& t = tracks_[free_hint];
        t = Track{};
        t.active = true;
        t.weed_part = det.weed_part;
        add_sighting(t, det, frame.seq);
        ++active_;
        ++counters_.tracks_created;
    }

    // 4. Confirmation, then 5. retirement.
    const double s_min = frame.view_s_min_mm;
    const double s_max = frame.view_s_max_mm;
    const bool view_ok = std::isfinite(s_min) && std::isfinite(s_max) && s_min <= s_max;
    for (std::size_t i = 0; i < cap; ++i) {
        Track& t = tracks_[i];
        if (!t.active)
            continue;
        // Behind the trailing edge: gone for good. Ahead of the leading edge
        // (a detection's noise at that edge, or reversing) counts as in view.
        const bool behind = view_ok && t.s_mm < s_min;
        if (!t.seen_this_frame && !behind)
            ++t.missed;
        if (!t.emitted && t.sightings >= 1) {
            if (t.sightings >= params_.confirm_frames)
                emit(t, frame, false);
            else if (view_ok && t.s_mm < s_min + params_.exit_margin_mm + t.extent_mm)
                emit(t, frame, true);
        }
        if (behind || t.missed >= params_.max_missed_frames)
            retire(i);
    }
    return {out_.get(), n_out_};
}

std::span<const RetiredTrack> Tracker::drain() noexcept
{
    n_out_ = 0;
    n_retired_ = 0;
    for (std::size_t i = 0; i < params_.capacity; ++i)
        if (tracks_[i].active)
            retire(i);
    return retired();
}

}  // namespace stemd::actuation
