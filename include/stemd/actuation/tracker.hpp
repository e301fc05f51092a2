// One target per plant: associates the detections of overlapping frames in
// field coordinates, fuses their positions, and emits each plant once.
//
// Coordinates are those of stemd/geometry/field.hpp: s_mm along-track (the
// odometer reading when the stem is under the camera's principal point),
// y_mm lateral. A plant does not move in these coordinates; the view moves
// forward (towards larger s) as the machine advances, so plants leave the
// view at its trailing edge, s_min.
//
// Per frame, update():
//  1. Association: every (detection, active track) pair closer than
//     association_radius_mm (Euclidean in s, y; strictly less) is a
//     candidate. Candidates are taken closest first, one-to-one: a track
//     takes at most one detection per frame and a detection joins at most
//     one track. Emitted tracks take part too, so that later sightings of
//     an emitted plant do not start a new track (and a second target).
//  2. Fusion: a track's position is the confidence-weighted mean of its
//     sightings (weight = confidence, at least kMinWeight). Its class is the
//     one with the larger summed confidence among crop / weed sightings
//     (unknown if none).
//  3. Unmatched detections start new tracks; when all `capacity` tracks are
//     in use the detection is dropped and counted (capacity_drops).
//  4. Confirmation: a track not yet emitted is emitted, once, when it has
//     been seen in >= confirm_frames frames, or when its fused s is within
//     exit_margin_mm + its extent of the trailing edge of the current view
//     (s < s_min + exit_margin_mm + extent_mm, which includes a track
//     already behind the view) with >= 1 sighting. The extent is the
//     largest along-track half-size of its sightings (0 if the caller does
//     not say): a plant whose leaves reach the trailing edge is about to be
//     cut by the image border, and a caller that ignores cut plants (as the
//     daemon does) sees it no more. exit_margin_mm should be at least the
//     distance travelled between two frames, so that a plant's last
//     sighting before it leaves falls in the margin.
//  5. Retirement: a track behind the current view (s < s_min) is retired
//     (after step 4, so an unemitted one leaving is emitted first); a track
//     not behind the view but unseen for max_missed_frames consecutive
//     frames is retired. A track ahead of the leading edge (s > s_max: a
//     detection's noise at that edge, or the machine reversing) counts as
//     in view. A frame with a non-finite or inverted extent retires nothing
//     by position and confirms nothing by exit. A retired track that was never emitted is counted
//     (retired_unconfirmed): a detection seen too few times in mid-view,
//     i.e. a false positive filtered out.
//
// Merge and split (e = the largest error of a single detection's position,
// e.g. 1 mm for ±1 mm noise; a fused position is within e of the truth):
//  - No merge: two plants at least association_radius_mm + 2e apart
//    (Euclidean) are never associated with each other's track, since a
//    detection of one is then at least association_radius_mm from the
//    other's track. This minimum spacing is min_separation_mm(e). Closer
//    plants usually stay apart too (one-to-one assignment when both are
//    seen in the same frame), but that is not guaranteed: a plant first
//    seen while its neighbour is missed joins the neighbour's track.
//  - Split: one plant becomes two targets if a detection lands
//    association_radius_mm or more from its own track, impossible while
//    association_radius_mm > 2e (so pick 2e < radius <= spacing - 2e), or
//    if it goes unseen for max_missed_frames frames while in view and is
//    then seen again (the new track is a new plant), or if its detection
//    is taken by a closer neighbouring track in a frame where the
//    neighbour itself is missed.
//
// Target ids count emitted targets modulo 4096 (the TARGET message's 12-bit
// target_id). Nothing allocates after construction; nothing throws.
// Single-threaded: the actuator thread owns it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

#include "stemd/base/plant_class.hpp"
#include "stemd/protocol/messages.hpp"

namespace stemd::actuation {

struct TrackerParams {
    double association_radius_mm = 10.0;
    std::uint32_t confirm_frames = 3;   // >= 1
    double exit_margin_mm = 60.0;       // >= 0; at least the travel between frames (46 mm at 5 km/h, 30 fps)
    std::uint32_t max_missed_frames = 3;  // >= 1
    std::size_t capacity = 256;         // tracks, preallocated (>= 1)
    std::size_t max_detections = 256;   // per frame; beyond this they are dropped and counted
};

// One detection of a frame, in field coordinates.
struct TrackDetection {
    double s_mm = 0;
    double y_mm = 0;
    float confidence = 1.0f;  // fusion weight, 0..1
    PlantClass plant_class = PlantClass::Unknown;
    std::uint8_t leaves = 0;
    double extent_mm = 0;     // along-track half-size of the plant (for the exit rule), >= 0
    // A weed part of a larger plant, or a further target on a wide weed
    // (vision::add_weed_parts): it lies within a few mm of the plant it
    // grew into or covers, so the two are tracked apart, each only with its
    // own kind; a part's sighting never votes weed on its crop's track.
    bool weed_part = false;
};

struct TrackFrame {
    std::uint64_t seq = 0;            // the frame's number (first/last frame of a track)
    std::int64_t t_sample_ns = 0;     // CLOCK_MONOTONIC of the exposure
    double odom_at_capture_mm = 0;
    double view_s_min_mm = 0;         // the view's along-track extent in field mm
    double view_s_max_mm = 0;         // (trailing edge s_min, leading edge s_max)
    std::span<const TrackDetection> detections;
};

// One plant, emitted once.
struct Target {
    std::uint16_t target_id = 0;  // 0..4095
    double s_mm = 0;              // fused
    double y_mm = 0;
    PlantClass plant_class = PlantClass::Unknown;
    std::uint32_t sightings = 0;  // frames it was seen in, up to confirmation
    std::uint8_t leaves = 0;      // the most leaves seen
    float confidence = 0;         // mean confidence of its sightings
    bool by_exit = false;         // emitted by the exit rule (fewer than confirm_frames sightings)
    std::int64_t t_emit_ns = 0;   // capture time of the frame that emitted it
    std::uint64_t first_seq = 0;  // the frame it was first seen in
};

// A track at the end of its life (behind the view, unseen too long, or
// drained): what the plant map records. Emitted tracks carry their
// target_id; the position is fused over every sighting, including those
// after the emission.
struct RetiredTrack {
    bool emitted = false;
    std::uint16_t target_id = 0;  // emitted only
    double s_mm = 0;
    double y_mm = 0;
    PlantClass plant_class = PlantClass::Unknown;
    std::uint32_t sightings = 0;
    std::uint8_t leaves = 0;
    float confidence = 0;
    std::uint64_t first_seq = 0;
    std::uint64_t last_seq = 0;   // the last frame it was seen in
};

struct TrackerCounters {
    std::uint64_t frames = 0;
    std::uint64_t tracks_created = 0;
    std::uint64_t confirmed = 0;            // targets emitted (by count or by exit)
    std::uint64_t confirmed_by_exit = 0;    // of which by the exit rule
    std::uint64_t retired = 0;              // all retired tracks
    std::uint64_t retired_unconfirmed = 0;  // retired without being emitted
    std::uint64_t capacity_drops = 0;       // detections dropped: no free track
    std::uint64_t detections_dropped = 0;   // beyond max_detections in one frame
    std::uint64_t rejected_detections = 0;  // non-finite position
};

class Tracker {
public:
    static constexpr double kMinWeight = 1e-3;

    // Parameters out of range are brought into range (see TrackerParams).
    explicit Tracker(const TrackerParams& params = {});

    // Processes one frame; returns the targets emitted by it (a view of an
    // internal buffer, valid until the next update() or reset()).
    std::span<const Target> update(const TrackFrame& frame) noexcept;

    // The spacing that guarantees two plants are never merged, for a
    // per-detection position error of at most max_error_mm.
    double min_separation_mm(double max_error_mm) const { return params_.association_radius_mm + 2 * max_error_mm; }

    const TrackerParams& params() const { return params_; }
    // The tracks retired by the last update() or drain() (a view of an
    // internal buffer, valid until the next update(), drain() or reset()).
    std::span<const RetiredTrack> retired() const { return {retired_.get(), n_retired_}; }
    // Retires every active track (end of a run), for retired().
    std::span<const RetiredTrack> drain() noexcept;

    const TrackerCounters& counters() const { return counters_; }
    std::size_t active_tracks() const { return active_; }
    // Drops every track (the counters and the target numbering go on).
    void reset() noexcept;

private:
    struct Track {
        bool active = false;
        bool emitted = false;
        bool seen_this_frame = false;
        std::uint32_t sightings = 0;
        std::uint32_t missed = 0;  // consecutive frames in view without a sighting
        double w_sum = 0;
        double ws_sum = 0;
        double wy_sum = 0;
        double s_mm = 0;  // fused
        double y_mm = 0;
        double crop_w = 0;
        double weed_w = 0;
        double conf_sum = 0;
        std::uint8_t leaves = 0;
        std::uint16_t target_id = 0;  // once emitted
        double extent_mm = 0;         // largest along-track half-size seen
        std::uint64_t first_seq = 0;
        std::uint64_t last_seq = 0;
        bool weed_part = false;       // a track of weed parts takes weed-part sightings only

        // The class of more weight among the sightings; a tie is Unknown.
        PlantClass plant_class() const
        {
            return weed_w > crop_w ? PlantClass::Weed : crop_w > weed_w ? PlantClass::Crop : PlantClass::Unknown;
        }
        float mean_confidence() const { return sightings > 0 ? static_cast<float>(conf_sum / sightings) : 0.0f; }
    };
    struct Candidate {
        double d2;
        std::uint32_t det;
        std::uint32_t track;
    };

    void add_sighting(Track& t, const TrackDetection& d, std::uint64_t seq) noexcept;
    void emit(Track& t, const TrackFrame& frame, bool by_exit) noexcept;
    void retire(std::size_t i) noexcept;

    TrackerParams params_;
    std::unique_ptr<Track[]> tracks_;
    std::unique_ptr<Candidate[]> candidates_;       // capacity * max_detections
    std::unique_ptr<std::uint32_t[]> det_track_;    // per detection: its track, or kNone
    std::unique_ptr<Target[]> out_;                 // capacity
    std::unique_ptr<RetiredTrack[]> retired_;       // capacity
    std::size_t n_retired_ = 0;
    std::size_t active_ = 0;
    std::size_t n_out_ = 0;
    std::uint32_t next_id_ = 0;
    TrackerCounters counters_;
};

}  // namespace stemd::actuation
