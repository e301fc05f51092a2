#include "stemd/vision/plants.hpp"

#include <algorithm>

namespace stemd::vision {

void LabelScratch::reserve(int width_px, int height_px)
{
    const std::size_t max_runs = static_cast<std::size_t>(width_px / 2 + 1) * static_cast<std::size_t>(height_px);
    runs_.reserve(max_runs);
    parent_.reserve(max_runs);
    run_component_.reserve(max_runs);
}

namespace {

int find_root(std::vector<int>& parent, int i)
{
    while (parent[static_cast<std::size_t>(i)] != i) {
        // Path halving keeps the trees flat without recursion.
        int& p = parent[static_cast<std::size_t>(i)];
        p = parent[static_cast<std::size_t>(p)];
        i = p;
    }
    return i;
}

// The smaller run index becomes the root, so each root is its component's
// first run in raster order.
void unite(std::vector<int>& parent, int a, int b)
{
    a = find_root(parent, a);
    b = find_root(parent, b);
    if (a < b)
        parent[static_cast<std::size_t>(b)] = a;
    else if (b < a)
        parent[static_cast<std::size_t>(a)] = b;
}

}  // namespace

void label_components(const BitMask& mask, LabelScratch& scratch, std::vector<Component>& out)
{
    auto& runs = scratch.runs_;
    auto& parent = scratch.parent_;
    runs.clear();
    parent.clear();
    out.clear();
    const int width = mask.width();
    const int words = mask.words_per_row();
    std::size_t previous_begin = 0, previous_end = 0;
    for (int y = 0; y < mask.height(); ++y) {
        const std::uint64_t* row = mask.row(y);
        const std::size_t current_begin = runs.size();
        std::size_t p = previous_begin;
        for (int x = next_bit(row, words, width, 0, true); x < width;) {
            const int end = next_bit(row, words, width, x, false);  // one past the run
            const int index = static_cast<int>(runs.size());
            runs.push_back({y, x, end - 1});
            parent.push_back(index);
            // 8-connectivity: runs touch if they overlap or meet diagonally.
            while (p < previous_end && runs[p].x1 < x - 1)
                ++p;
            for (std::size_t q = p; q < previous_end && runs[q].x0 <= end; ++q)
                unite(parent, index, static_cast<int>(q));
            x = next_bit(row, words, width, end, true);
        }
        previous_begin = current_begin;
        previous_end = runs.size();
    }

    // A root is its component's first run, so its component is known before
    // any other run of it is reached.
    auto& component = scratch.run_component_;
    component.assign(runs.size(), -1);
    for (std::size_t i = 0; i < runs.size(); ++i) {
        const int root = find_root(parent, static_cast<int>(i));
        const auto& run = runs[i];
        if (root == static_cast<int>(i)) {
            component[i] = static_cast<int>(out.size());
            Component c;
            c.x_min = run.x0;
            c.x_max = run.x1;
            c.y_min = c.y_max = run.y;
            c.first_pixel = {run.x0, run.y};
            out.push_back(c);
        }
        component[i] = component[static_cast<std::size_t>(root)];
        Component& c = out[static_cast<std::size_t>(component[i])];
        const long n = run.x1 - run.x0 + 1;
        c.area_px += n;
        c.sum_x += static_cast<double>(run.x0 + run.x1) * static_cast<double>(n) / 2.0;
        c.sum_y += static_cast<double>(run.y) * static_cast<double>(n);
        c.x_min = std::min(c.x_min, run.x0);
        c.x_max = std::max(c.x_max, run.x1);
        c.y_max = run.y;
    }
    scratch.component_count_ = out.size();
}

int component_at(const LabelScratch& scratch, cv::Point p)
{
    const auto& runs = scratch.runs_;
    // Runs are in raster order: the last one starting at or before p.
    const auto after = std::upper_bound(runs.begin(), runs.end(), p, [](cv::Point q, const LabelScratch::Run& r) {
        return q.y < r.y || (q.y == r.y && q.x < r.x0);
    });
    if (after == runs.begin())
        return -1;
    const auto run = std::prev(after);
    if (run->y != p.y || p.x > run->x1)
        return -1;
    return scratch.run_component_[static_cast<std::size_t>(run - runs.begin())];
}

void reduce_labelled_mask(const LabelScratch& scratch, int cell_px, BitMask& out)
{
    out.clear();
    for (const LabelScratch::Run& run : scratch.runs_) {
        const int y = run.y / cell_px;
        if (y >= out.height())
            continue;
        const int last = std::min(run.x1 / cell_px, out.width() - 1);
        for (int x = run.x0 / cell_px; x <= last; ++x)
            out.set(x, y);
    }
}

namespace {

// Whether any bit x0..x1 (inclusive) of a row is set, or sets them all.
bool any_in_range(const std::uint64_t* row, int x0, int x1)
{
    for (int w = x0 >> 6; w <= (x1 >> 6); ++w)
        if (row[w] & range_bits_of_word(w, x0, x1))
            return true;
    return false;
}

void set_range(std::uint64_t* row, int x0, int x1)
{
    for (int w = x0 >> 6; w <= (x1 >> 6); ++w)
        row[w] |= range_bits_of_word(w, x0, x1);
}

}  // namespace

void mark_seeded_components(const LabelScratch& scratch, const BitMask& seeds, std::vector<std::uint8_t>& keep)
{
    keep.assign(scratch.component_count(), 0);
    for (std::size_t i = 0; i < scratch.run_count(); ++i) {
        const LabelScratch::LabelledRun run = scratch.run(i);
        if (any_in_range(seeds.row(run.y), run.x0, run.x1))
            keep[static_cast<std::size_t>(run.component)] = 1;
    }
}

void paint_kept_components(const LabelScratch& scratch, const std::vector<std::uint8_t>& keep, BitMask& out)
{
    out.clear();
    for (std::size_t i = 0; i < scratch.run_count(); ++i) {
        const LabelScratch::LabelledRun run = scratch.run(i);
        if (keep[static_cast<std::size_t>(run.component)])
            set_range(out.row(run.y), run.x0, run.x1);
    }
}

}  // namespace stemd::vision
