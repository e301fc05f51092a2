// Drawing a plant: each leaf, grass blade and crown is one anti-aliased
// layer composited over the image, its hard fill going into the mask;
// fragmentation cuts gaps and holes out of both.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "plant.hpp"
#include "random.hpp"

namespace stemd::synth {

struct Canvas {
    cv::Mat bgr, nir, mask;
    std::vector<float> leaf_texture;   // per pixel, about -1..1: blotches on the leaves
    cv::Mat plant_class;               // optional (strips): PlantClass values
};

// Draws a plant (longest leaves first: the young short ones sit on top,
// then the crown) and returns its mask pixels as ground truth; with
// mask_out, also its own mask (over *box_out). A canvas with a class map
// gets the plant's class on its mask pixels.
GroundTruthStem render_plant(Canvas& canvas, const Plant& plant, double fragmentation, double px_per_mm, Rng& rng,
                             cv::Mat* mask_out = nullptr, cv::Rect* box_out = nullptr);

}  // namespace stemd::synth
