#include "stemd/vision/leaves.hpp"

#include <algorithm>
#include <cmath>

namespace stemd::vision {

namespace {

long long cross(const cv::Point& o, const cv::Point& a, const cv::Point& b)
{
    return static_cast<long long>(a.x - o.x) * (b.y - o.y) - static_cast<long long>(a.y - o.y) * (b.x - o.x);
}

}  // namespace

void convex_hull_indices(std::span<const cv::Point> contour, std::vector<int>& hull, std::vector<int>& order)
{
    hull.clear();
    order.clear();
    const int n = static_cast<int>(contour.size());
    if (n == 0)
        return;
    auto at = [&](int i) -> const cv::Point& { return contour[static_cast<std::size_t>(i)]; };
    // The hull of pixel points is the hull of each column's top-most and
    // bottom-most point; listing those column by column sorts them by
    // (x, y) in O(n + width), with no comparison sort.
    int x_min = at(0).x, x_max = at(0).x;
    for (const cv::Point& p : contour) {
        x_min = std::min(x_min, p.x);
        x_max = std::max(x_max, p.x);
    }
    const int columns = x_max - x_min + 1;
    order.assign(static_cast<std::size_t>(2 * columns), -1);  // [top, bottom] per column
    for (int i = 0; i < n; ++i) {
        const cv::Point& p = at(i);
        int& top = order[static_cast<std::size_t>(2 * (p.x - x_min))];
        int& bottom = order[static_cast<std::size_t>(2 * (p.x - x_min) + 1)];
        if (top < 0 || p.y < at(top).y)
            top = i;  // first occurrence wins among repeated points
        if (bottom < 0 || p.y > at(bottom).y)
            bottom = i;
    }
    // Compact to the sorted candidate list (a column's top and bottom may coincide).
    std::size_t m = 0;
    for (int c = 0; c < columns; ++c) {
        const int top = order[static_cast<std::size_t>(2 * c)];
        const int bottom = order[static_cast<std::size_t>(2 * c + 1)];
        if (top < 0)
            continue;
        order[m++] = top;
        if (at(bottom).y != at(top).y)
            order[m++] = bottom;
    }
    order.resize(m);
    const int k = static_cast<int>(m);
    // Andrew's monotone chain; collinear points are dropped.
    for (int pass = 0; pass < 2; ++pass) {
        const std::size_t base = hull.size();
        for (int j = 0; j < k; ++j) {
            const int i = order[static_cast<std::size_t>(pass == 0 ? j : k - 1 - j)];
            while (hull.size() >= base + 2 && cross(at(hull[hull.size() - 2]), at(hull.back()), at(i)) <= 0)
                hull.pop_back();
            hull.push_back(i);
        }
        hull.pop_back();  // the chain's last point starts the other chain
    }
    // Contour order, one index per distinct hull vertex.
    std::sort(hull.begin(), hull.end());
    hull.erase(std::unique(hull.begin(), hull.end(), [&](int a, int b) { return at(a) == at(b); }), hull.end());
    if (hull.empty())
        hull.push_back(order.front());
}

double convex_hull_area_px(std::span<const cv::Point> contour, std::span<const int> hull)
{
    if (hull.empty())
        return 0;
    double twice_area = 0, perimeter = 0;
    const cv::Point& origin = contour[static_cast<std::size_t>(hull[0])];
    for (std::size_t k = 0; k < hull.size(); ++k) {
        const cv::Point a = contour[static_cast<std::size_t>(hull[k])] - origin;
        const cv::Point b = contour[static_cast<std::size_t>(hull[(k + 1) % hull.size()])] - origin;
        twice_area += static_cast<double>(a.x) * b.y - static_cast<double>(b.x) * a.y;
        perimeter += std::hypot(static_cast<double>(b.x - a.x), static_cast<double>(b.y - a.y));
    }
    return 0.5 * std::abs(twice_area) + 0.5 * perimeter + 1.0;
}

void convexity_defects(std::span<const cv::Point> contour, std::span<const int> hull, float min_depth_px,
                       std::vector<Defect>& out)
{
    out.clear();
    const int n = static_cast<int>(contour.size());
    const int h = static_cast<int>(hull.size());
    if (n < 3 || h < 2)
        return;
    for (int k = 0; k < h; ++k) {
        const int start = hull[static_cast<std::size_t>(k)];
        const int end = hull[static_cast<std::size_t>((k + 1) % h)];
        const int span_end = end > start ? end : end + n;  // the last edge wraps around
        const cv::Point& a = contour[static_cast<std::size_t>(start)];
        const cv::Point& b = contour[static_cast<std::size_t>(end)];
        const double edge_x = b.x - a.x, edge_y = b.y - a.y;
        const double edge_length = std::hypot(edge_x, edge_y);
        double best_depth = 0;
        int deepest = -1;
        for (int j = start + 1; j < span_end; ++j) {
            const cv::Point& p = contour[static_cast<std::size_t>(j % n)];
            const double depth = edge_length > 0
                                     ? std::abs(edge_x * (p.y - a.y) - edge_y * (p.x - a.x)) / edge_length
                                     : std::hypot(p.x - a.x, p.y - a.y);
            if (depth > best_depth) {
                best_depth = depth;
                deepest = j % n;
            }
        }
        if (deepest >= 0 && best_depth > min_depth_px && out.size() < out.capacity())
            out.push_back({start, end, deepest, static_cast<float>(best_depth)});
    }
    // The wrapping edge can put its cut before the others.
    std::sort(out.begin(), out.end(), [](const Defect& x, const Defect& y) { return x.deepest < y.deepest; });
}

Leaf leaf_from_polygon(std::span<const cv::Point> contour, int from, int to)
{
    const int n = static_cast<int>(contour.size());
    // Green's theorem over the contour from one cut to the next, closed
    // by the cut: area, centroid and second moments of the leaf polygon,
    // in coordinates relative to the first cut for numerical headroom.
    double twice_area = 0, cx = 0, cy = 0, mean_x = 0, mean_y = 0, sxx = 0, syy = 0, sxy = 0;
    const cv::Point& first = contour[static_cast<std::size_t>(from)];
    for (int j = from; j <= to; ++j) {
        const cv::Point p = contour[static_cast<std::size_t>(j % n)] - first;
        const cv::Point q = (j < to ? contour[static_cast<std::size_t>((j + 1) % n)] : first) - first;
        const double c = static_cast<double>(p.x) * q.y - static_cast<double>(q.x) * p.y;
        twice_area += c;
        cx += (p.x + q.x) * c;
        cy += (p.y + q.y) * c;
        sxx += (static_cast<double>(p.x) * p.x + static_cast<double>(p.x) * q.x + static_cast<double>(q.x) * q.x) * c;
        syy += (static_cast<double>(p.y) * p.y + static_cast<double>(p.y) * q.y + static_cast<double>(q.y) * q.y) * c;
        sxy += (2.0 * p.x * p.y + 2.0 * q.x * q.y + static_cast<double>(p.x) * q.y + static_cast<double>(q.x) * p.y) * c;
        mean_x += p.x;
        mean_y += p.y;
    }
    const int count = to - from + 1;
    Leaf leaf;
    leaf.cut_a = cv::Point2f(first);
    leaf.cut_b = cv::Point2f(contour[static_cast<std::size_t>(to % n)]);
    leaf.root = (leaf.cut_a + leaf.cut_b) * 0.5f;
    const cv::Point2f origin(first);
    if (std::abs(twice_area) >= 1.0) {
        const double gx = cx / (3.0 * twice_area), gy = cy / (3.0 * twice_area);
        leaf.centre = origin + cv::Point2f(static_cast<float>(gx), static_cast<float>(gy));
        // Central second moments (per unit area) and their principal axis.
        const double area = 0.5 * twice_area;
        const double mu20 = sxx / 12.0 / area - gx * gx;
        const double mu02 = syy / 12.0 / area - gy * gy;
        const double mu11 = sxy / 24.0 / area - gx * gy;
        const double theta = 0.5 * std::atan2(2.0 * mu11, mu20 - mu02);
        const double spread = std::sqrt(0.25 * (mu20 - mu02) * (mu20 - mu02) + mu11 * mu11);
        const double major = 0.5 * (mu20 + mu02) + spread, minor = 0.5 * (mu20 + mu02) - spread;
        leaf.axis = {static_cast<float>(std::cos(theta)), static_cast<float>(std::sin(theta))};
        leaf.elongation = minor > 1e-9 ? static_cast<float>(major / minor) : 1e6f;
    } else {
        leaf.centre = origin + cv::Point2f(static_cast<float>(mean_x / count), static_cast<float>(mean_y / count));
        leaf.axis = {1, 0};
        leaf.elongation = 1;
    }
    return leaf;
}

int leaves_from_defects(std::span<const cv::Point> contour, std::span<const Defect> defects,
                        FixedVector<Leaf, kMaxLeaves>& out)
{
    out.clear();
    const int n = static_cast<int>(contour.size());
    const int d = static_cast<int>(defects.size());
    if (d < 2 || n == 0)
        return 0;
    int dropped = 0;
    for (int k = 0; k < d; ++k) {
        const int from = defects[static_cast<std::size_t>(k)].deepest;
        int to = defects[static_cast<std::size_t>((k + 1) % d)].deepest;
        if (to <= from)
            to += n;
        const Leaf leaf = leaf_from_polygon(contour, from, to);
        if (!out.push_back(leaf))
            ++dropped;
    }
    return dropped;
}

}  // namespace stemd::vision
