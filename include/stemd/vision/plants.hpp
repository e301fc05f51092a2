// Plants = 8-connected components of the closed mask, found on runs of
// set bits (union-find over runs of neighbouring rows). Holes are
// background and never become plants.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core/types.hpp>

#include "stemd/vision/bitmask.hpp"

namespace stemd::vision {

struct Component {
    long area_px = 0;
    int x_min = 0, y_min = 0, x_max = 0, y_max = 0;   // inclusive
    double sum_x = 0, sum_y = 0;                       // for the centre of mass
    cv::Point first_pixel;                             // top-most, then left-most
};

class LabelScratch {
public:
    // Enough for any mask of this size: at most (w/2 + 1) runs per row.
    void reserve(int width_px, int height_px);
    std::size_t reserved_bytes() const
    {
        return runs_.capacity() * sizeof(Run) + (parent_.capacity() + run_component_.capacity()) * sizeof(int);
    }

    // After label_components: its runs in raster order (x1 inclusive), each
    // with the index (into label_components' `out`) of its component, so a
    // pass over the labelled mask needs neither a bit scan nor a lookup.
    struct LabelledRun {
        int y, x0, x1, component;
    };
    std::size_t run_count() const { return runs_.size(); }
    LabelledRun run(std::size_t i) const
    {
        const Run& r = runs_[i];
        return {r.y, r.x0, r.x1, run_component_[i]};
    }
    // After label_components: how many components its `out` holds.
    std::size_t component_count() const { return component_count_; }

private:
    friend void label_components(const BitMask&, LabelScratch&, std::vector<Component>&);
    friend int component_at(const LabelScratch&, cv::Point);
    friend void reduce_labelled_mask(const LabelScratch&, int, BitMask&);
    struct Run { int y, x0, x1; };
    std::vector<Run> runs_;
    std::vector<int> parent_;
    std::vector<int> run_component_;
    std::size_t component_count_ = 0;
};

// Components in raster order of their first pixel. `out` is cleared and
// refilled; reserve it (one entry per possible run) to avoid allocations.
void label_components(const BitMask& mask, LabelScratch& scratch, std::vector<Component>& out);

// After label_components: the labelled mask reduced by `cell_px` in both
// directions (a cell is set when any of its pixels is), drawn from the runs
// alone. `out` must be at least (width / cell_px + 1) x (height / cell_px +
// 1); it is cleared first.
void reduce_labelled_mask(const LabelScratch& scratch, int cell_px, BitMask& out);

// After label_components, a reconstruction by dilation in two steps, with
// room for a test of the kept components between them: `keep` (one entry
// per component, resized; reserve it) = 1 for each component holding at
// least one set pixel of `seeds` (same size), then `out` (cleared first) =
// the components whose `keep` is set, whole and unchanged.
void mark_seeded_components(const LabelScratch& scratch, const BitMask& seeds, std::vector<std::uint8_t>& keep);
void paint_kept_components(const LabelScratch& scratch, const std::vector<std::uint8_t>& keep, BitMask& out);

// After label_components: the index (into its `out`) of the component
// holding pixel `p`, or -1 if `p` is background. O(log runs), no allocation.
int component_at(const LabelScratch& scratch, cv::Point p);

}  // namespace stemd::vision
