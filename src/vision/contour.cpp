#include "stemd/vision/contour.hpp"

namespace stemd::vision {

namespace {

// Chain codes 0..7, counter-clockwise as displayed (y grows downwards):
// right, up-right, up, up-left, left, down-left, down, down-right.
constexpr int kDx[8] = {1, 1, 0, -1, -1, -1, 0, 1};
constexpr int kDy[8] = {0, -1, -1, -1, 0, 1, 1, 1};

}  // namespace

bool trace_outer_contour(const BitMask& mask, cv::Point start, std::vector<cv::Point>& contour)
{
    contour.clear();
    auto emit = [&](cv::Point p) {
        if (contour.size() == contour.capacity())
            return false;
        contour.push_back(p);
        return true;
    };
    if (!mask.get_or_zero(start.x, start.y))
        return true;

    // Suzuki & Abe (1985), outer border: the start pixel's left neighbour is
    // background. Search clockwise from there for the border's last pixel.
    int direction = 4;
    cv::Point last;
    bool found = false;
    for (int step = 0; step < 7; ++step) {
        direction = (direction + 7) & 7;
        last = {start.x + kDx[direction], start.y + kDy[direction]};
        if (mask.get_or_zero(last.x, last.y)) {
            found = true;
            break;
        }
    }
    if (!found)
        return emit(start);  // an isolated pixel

    // Walk counter-clockwise: from each pixel, search its neighbours
    // counter-clockwise starting just after the one we came from. Stop when
    // we are back at the start having arrived from its last pixel.
    cv::Point current = start;
    for (;;) {
        cv::Point next;
        for (int step = 0; step < 8; ++step) {
            direction = (direction + 1) & 7;
            next = {current.x + kDx[direction], current.y + kDy[direction]};
            if (mask.get_or_zero(next.x, next.y))
                break;
        }
        if (!emit(current))
            return false;
        if (next == start && current == last)
            return true;
        current = next;
        direction = (direction + 4) & 7;  // points back to where we came from
    }
}

}  // namespace stemd::vision
