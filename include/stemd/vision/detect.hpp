// The whole pipeline: index -> smoothing -> threshold -> opening -> mixed
// edge pixels -> closing -> plants -> leaves -> stems.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/closing.hpp"
#include "stemd/vision/edges.hpp"
#include "stemd/vision/index.hpp"
#include "stemd/vision/leaves.hpp"
#include "stemd/vision/plants.hpp"
#include "stemd/vision/sparse_index.hpp"
#include "stemd/vision/threshold.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::vision {

// Borrowed views of one frame. bgr: CV_8UC3; nir: CV_8UC1 (ndvi only);
// mask: CV_8UC1 (mask segmentation only). Any of them may be empty when
// the segmentation does not use it.
struct FrameView {
    cv::Mat bgr{};
    cv::Mat nir{};
    cv::Mat mask{};
};

// Every buffer one frame needs, allocated by the constructor for one frame
// size; detect() then allocates nothing. One per processing thread.
class Workspace {
public:
    Workspace(cv::Size frame_size, const Params& params);
    cv::Size frame_size() const { return frame_size_; }
    // Heap memory held for frames of this size (worst-case bounds).
    std::size_t reserved_bytes() const;

    // Intermediate results of the last detect(), for tools and overlays.
    const cv::Mat& index() const { return index_; }
    const BitMask& vegetation() const { return vegetation_; }
    const BitMask& closed() const { return closed_; }
    // The pieces (connected components) of the closed mask, and per piece
    // 1 + the index of the plant it belongs to in detect()'s output, 0 for
    // pieces of no plant (too small, over capacity): how classify finds each
    // closed pixel's plant without grouping the pieces again.
    const LabelScratch& pieces() const { return labels_; }
    std::span<const std::uint16_t> piece_plant() const { return piece_plant_; }

private:
    friend void detect(const FrameView&, const Params&, Workspace&, Detections&, StageTimes*);
    friend void compute_index(const FrameView&, Segmentation, const Params&, Workspace&, bool);
    friend void sort_pieces_by_group(Workspace&);
    friend int group_end(const Workspace&, int);
    friend bool has_own_leaves(const Component&, const Params&, Workspace&);
    friend bool split_groups_at_rosettes(const Params&, Workspace&);
    friend void threshold_index(const FrameView&, Segmentation, const Params&, Workspace&, DetectStats&, BitMask&,
                                std::int64_t&);
    cv::Size frame_size_;
    int reserved_radius_px_ = 0;
    cv::Mat raw_index_;                     // before smoothing
    cv::Mat index_;                         // what the threshold sees
    cv::Mat green_index_;                   // exg_and_ndvi: chromatic ExG where the greenness test reads it
    std::vector<std::uint16_t> smooth_row_;
    SparseIndexScratch sparse_;
    bool sparse_pending_ = false;           // the index left soil tiles uncomputed
    Histogram histogram_{};
    BitMask vegetation_;                    // thresholded components the opening left a seed in
    BitMask thresholded_;
    BitMask second_;                        // exg_and_ndvi: the chromatic ExG mask, where seeds must lie
    BitMask opened_;                        // seeds: the opening (NIR path) or its erosion, which seeds the same components
    std::vector<std::uint8_t> keep_;        // per thresholded component: seeded
    std::vector<std::uint8_t> fringe_passed_;  // per thresholded component: the slides its green survived
    BitMask edged_;                         // vegetation_ with its mixed edge pixels
    EdgeScratch edges_;
    BitMask closed_;
    ClosingScratch opening_;
    ClosingScratch closing_;
    LabelScratch labels_;
    std::vector<Component> components_;     // pieces of the closed mask
    BitMask cells_;                         // the closed mask in grouping cells
    BitMask grouped_;                       // cells_ dilated by half the group gap
    ClosingScratch grouping_;
    LabelScratch group_labels_;
    std::vector<Component> groups_;         // components of grouped_
    std::vector<int> piece_group_;          // per piece: its group
    std::vector<int> piece_order_;          // pieces sorted by group
    std::vector<int> group_rank_;           // per group: its rank by first piece
    std::vector<std::uint16_t> piece_plant_;   // per piece: 1 + its plant's index, 0 = none
    std::vector<std::uint8_t> piece_rosette_;  // per piece of a group: has leaves of its own
    std::vector<cv::Point> contour_;
    std::vector<int> hull_;
    std::vector<int> hull_order_;
    std::vector<Defect> defects_;
};

// Fills `out` (cleared first). A frame the workspace was not made for, or
// one missing the image its segmentation needs, leaves out.status != ok
// and no plants; nothing throws. `times` (optional) gets per-stage times.
void detect(const FrameView& frame, const Params& params, Workspace& workspace, Detections& out,
            StageTimes* times = nullptr);

// Convenience for tests and tools: allocates a workspace for this frame.
Detections detect(const FrameView& frame, const Params& params);

}  // namespace stemd::vision
