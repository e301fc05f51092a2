#include "stemd/viz/overlay.hpp"

#include <vector>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/contour.hpp"
#include "stemd/vision/leaves.hpp"

namespace stemd::viz {

namespace {

const cv::Scalar kContour(0, 255, 0);
const cv::Scalar kHull(0, 0, 255);
const cv::Scalar kCut(0, 0, 255);
const cv::Scalar kLeaf(255, 255, 255);
const cv::Scalar kStemLeaves(0, 0, 255);
const cv::Scalar kStemCom(0, 165, 255);
const cv::Scalar kCentreOfMass(255, 128, 0);

cv::Point px(cv::Point2f p) { return {cvRound(p.x), cvRound(p.y)}; }

void diamond(cv::Mat& canvas, cv::Point2f c, int r, const cv::Scalar& colour)
{
    const std::vector<cv::Point> pts{px(c + cv::Point2f(0, -r)), px(c + cv::Point2f(r, 0)), px(c + cv::Point2f(0, r)),
                                     px(c + cv::Point2f(-r, 0))};
    cv::polylines(canvas, pts, true, colour, 2, cv::LINE_AA);
}

}  // namespace

void draw_overlay(cv::Mat& canvas, const vision::Detections& detections, const vision::BitMask& closed)
{
    std::vector<cv::Point> contour;
    contour.reserve(static_cast<std::size_t>(closed.width() + closed.height()) * 16);
    std::vector<int> hull, order;
    for (const vision::Plant& plant : detections.plants) {
        vision::trace_outer_contour(closed, plant.first_pixel, contour);
        if (!contour.empty()) {
            cv::polylines(canvas, contour, true, kContour, 1, cv::LINE_8);
            order.reserve(contour.size());
            vision::convex_hull_indices(contour, hull, order);
            std::vector<cv::Point> hull_points;
            for (const int i : hull)
                hull_points.push_back(contour[static_cast<std::size_t>(i)]);
            cv::polylines(canvas, hull_points, true, kHull, 1, cv::LINE_AA);
        }
        for (const vision::Leaf& leaf : plant.leaves) {
            cv::circle(canvas, px(leaf.cut_a), 4, kCut, 2, cv::LINE_AA);
            // The leaf direction, drawn from the centre through the root to the stem.
            cv::line(canvas, px(leaf.centre), px(plant.method == vision::StemMethod::leaves ? plant.stem : leaf.root),
                     kLeaf, 1, cv::LINE_AA);
            cv::drawMarker(canvas, px(leaf.root), kLeaf, cv::MARKER_CROSS, 10, 2);
            diamond(canvas, leaf.centre, 5, kLeaf);
        }
        cv::drawMarker(canvas, px(plant.centre_of_mass), kCentreOfMass, cv::MARKER_SQUARE, 8, 2);
        if (!plant.has_stem) {
            // Stemless (grass, or too unsure): a grey cross, no stem.
            cv::drawMarker(canvas, px(plant.centre_of_mass), cv::Scalar(160, 160, 160), cv::MARKER_TILTED_CROSS, 14, 2);
            continue;
        }
        const bool from_leaves = plant.method == vision::StemMethod::leaves;
        cv::circle(canvas, px(plant.stem), 6, from_leaves ? kStemLeaves : kStemCom, cv::FILLED, cv::LINE_AA);
        cv::circle(canvas, px(plant.stem), 7, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    }
}

}  // namespace stemd::viz
