// Plants as parameters: leaves (petiole + blade, or a grass blade) around a
// stem, and the geometry of their outlines.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "polygon.hpp"
#include "stemd/base/plant_class.hpp"

namespace stemd::synth {

// A rosette of petiole + blade leaves around a stem, or a stemless tuft of
// grass blades (a weed).
enum class PlantShape { rosette, grass_tuft };
enum class BladeShape { ovate, linear };

// One leaf in the stem's frame (px). The centreline bends sideways with
// the square of the distance; the half width is the petiole's up to
// petiole_length_px, then a teardrop blade (ovate), or for grass (linear)
// a taper from petiole_half_px at the base to 0 at the tip.
struct LeafParams {
    double angle_rad = 0;
    double length_px = 0;
    double petiole_length_px = 0;
    double petiole_half_px = 0;
    double blade_half_px = 0;
    double peak_t = 0.5;   // where the blade is widest, 0..1 along the blade
    double bend = 0;       // sideways offset of the tip, fraction of length
    BladeShape shape = BladeShape::ovate;
    double shade = 1;      // brightness factor of this leaf
    double nir_shift = 0;
};

struct Plant {
    PlantClass plant_class = PlantClass::Crop;
    PlantShape shape = PlantShape::rosette;
    cv::Point2d stem_px;
    double crown_radius_px = 0;
    std::vector<LeafParams> leaves;
    cv::Vec3d bgr;   // base colour
    double nir = 0;
};

cv::Point2d direction(const LeafParams& leaf);
// The centreline at s px from the stem, and its unit normal there.
cv::Point2d centre_point(const LeafParams& leaf, double s);
cv::Point2d centre_normal(const LeafParams& leaf, double s);
double half_width(const LeafParams& leaf, double s);
Polygon leaf_outline(const LeafParams& leaf);

// Quadrilateral across the centreline at s: `along` wide along the leaf,
// from `from` to `to` (signed distances from the centreline, px).
Polygon cross_band(const LeafParams& leaf, cv::Point2d stem, double s, double along, double from, double to);
// Stem to the farthest point of the plant, px.
double plant_extent_px(const Plant& plant);
void scale_plant(Plant& plant, double factor);

}  // namespace stemd::synth
