// Helpers shared by the vision tests: deterministic random masks, a mask's
// pieces as the pipeline labels them, and a misregistered green plane.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/vision/bitmask.hpp"
#include "stemd/vision/plants.hpp"

namespace stemd::test {

// Random blobs (filled circles and thick lines) on an empty mask, 255 = set,
// plus salt noise of the given density. Deterministic in `seed`.
inline cv::Mat random_blob_mask(cv::Size size, std::uint64_t seed, int blobs, double salt_density)
{
    cv::RNG rng(seed);
    cv::Mat mask = cv::Mat::zeros(size, CV_8UC1);
    for (int i = 0; i < blobs; ++i) {
        const cv::Point c(rng.uniform(-5, size.width + 5), rng.uniform(-5, size.height + 5));
        if (rng.uniform(0, 2) == 0) {
            cv::circle(mask, c, rng.uniform(1, 12), 255, cv::FILLED, cv::LINE_8);
        } else {
            const cv::Point d(rng.uniform(-25, 25), rng.uniform(-25, 25));
            cv::line(mask, c, c + d, 255, rng.uniform(1, 4), cv::LINE_8);
        }
    }
    const int salt = static_cast<int>(salt_density * size.area());
    for (int i = 0; i < salt; ++i)
        mask.at<std::uint8_t>(rng.uniform(0, size.height), rng.uniform(0, size.width)) = 255;
    return mask;
}

// A mask (nonzero = set) packed and labelled into its 8-connected pieces;
// the packed mask and the labels stay for the checks.
struct LabelledMask {
    explicit LabelledMask(const cv::Mat& mask)
    {
        vision::pack_mask(mask, vision::MaskVegetation::nonzero, bits);
        scratch.reserve(mask.cols, mask.rows);
        vision::label_components(bits, scratch, components);
    }
    vision::BitMask bits;
    vision::LabelScratch scratch;
    std::vector<vision::Component> components;
};

// The green plane of a BGR frame slid one pixel to the right (its first
// column kept), as a lens's lateral chromatic aberration or the Bayer
// interpolation misregisters it against the red and blue.
inline void slide_green_plane_right(cv::Mat& bgr)
{
    cv::Mat planes[3];
    cv::split(bgr, planes);
    cv::Mat slid = planes[1].clone();
    planes[1](cv::Rect(0, 0, bgr.cols - 1, bgr.rows)).copyTo(slid(cv::Rect(1, 0, bgr.cols - 1, bgr.rows)));
    planes[1] = slid;
    cv::merge(planes, 3, bgr);
}

}  // namespace stemd::test
