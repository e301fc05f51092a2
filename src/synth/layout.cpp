#include "layout.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace stemd::synth {
namespace {

constexpr double kPi = std::numbers::pi;

// Leaf angles: evenly spaced, then jittered by up to 30 % of the spacing,
// so neighbours keep at least 40 % of it (concavities between leaves).
std::vector<double> leaf_angles_rad(int count, Rng& rng)
{
    const double spacing = 2 * kPi / count;
    const double base = rng.uniform(0, 2 * kPi);
    std::vector<double> angles;
    for (int i = 0; i < count; ++i)
        angles.push_back(base + i * spacing + rng.uniform(-0.3, 0.3) * spacing);
    return angles;
}

// Unequal leaves (random factor 0.55..1.25, longest = radius) so that the
// centre of mass is off the stem.
std::vector<double> leaf_lengths_px(int count, double radius_px, Rng& rng)
{
    std::vector<double> factors;
    for (int i = 0; i < count; ++i)
        factors.push_back(rng.uniform(0.55, 1.25));
    const double longest = *std::max_element(factors.begin(), factors.end());
    for (double& f : factors)
        f *= radius_px / longest;
    return factors;
}

cv::Vec3d plant_colour_bgr(PlantClass plant_class, PlantShape shape, Rng& rng)
{
    if (shape == PlantShape::grass_tuft)
        return {rng.uniform(40, 60), rng.uniform(130, 165), rng.uniform(95, 125)};
    if (plant_class == PlantClass::Crop)   // sugar beet: medium green
        return {rng.uniform(35, 60), rng.uniform(110, 145), rng.uniform(55, 85)};
    // Weeds: yellowish or dark bluish green, to differ from the crop.
    if (rng.chance(0.5))
        return {rng.uniform(30, 50), rng.uniform(120, 160), rng.uniform(80, 110)};
    return {rng.uniform(55, 75), rng.uniform(100, 125), rng.uniform(40, 60)};
}

LeafParams rosette_leaf(PlantClass plant_class, double angle_rad, double length_px, double px_per_mm, Rng& rng)
{
    const bool crop = plant_class == PlantClass::Crop;
    LeafParams leaf;
    leaf.angle_rad = angle_rad;
    leaf.length_px = length_px;
    leaf.petiole_length_px = length_px * (crop ? rng.uniform(0.25, 0.38) : rng.uniform(0.15, 0.3));
    // Petioles 1-2 mm wide on crops, thinner on weeds; never wider than a
    // fraction of the leaf, which matters for the smallest weeds.
    const double petiole_half_mm = crop ? rng.uniform(0.5, 1.0) : rng.uniform(0.3, 0.5);
    leaf.petiole_half_px = std::min(petiole_half_mm * px_per_mm, 0.12 * length_px);
    const double blade_px = length_px - leaf.petiole_length_px;
    leaf.blade_half_px = blade_px * (crop ? rng.uniform(0.3, 0.4) : rng.uniform(0.18, 0.28));
    leaf.peak_t = crop ? rng.uniform(0.4, 0.55) : rng.uniform(0.35, 0.5);
    leaf.bend = crop ? rng.uniform(-0.08, 0.08) : rng.uniform(-0.12, 0.12);
    leaf.shade = rng.uniform(0.82, 1.12);
    leaf.nir_shift = rng.uniform(-12, 12);
    return leaf;
}

}  // namespace

Plant make_rosette(PlantClass plant_class, const PlantClassSpec& spec, double px_per_mm, Rng& rng)
{
    Plant plant;
    plant.plant_class = plant_class;
    const double radius_px = rng.uniform(spec.radius_mm.lo, spec.radius_mm.hi) * px_per_mm;
    const int count = rng.uniform_int(spec.leaves.lo, spec.leaves.hi);
    const std::vector<double> angles = leaf_angles_rad(count, rng);
    const std::vector<double> lengths = leaf_lengths_px(count, radius_px, rng);
    for (int i = 0; i < count; ++i)
        plant.leaves.push_back(rosette_leaf(plant_class, angles[i], lengths[i], px_per_mm, rng));
    const double crown_mm = plant_class == PlantClass::Crop ? rng.uniform(1.0, 2.0) : rng.uniform(0.4, 0.8);
    plant.crown_radius_px = std::min(crown_mm * px_per_mm, 0.2 * radius_px);
    plant.bgr = plant_colour_bgr(plant_class, PlantShape::rosette, rng);
    plant.nir = plant_class == PlantClass::Crop ? rng.uniform(190, 220) : rng.uniform(180, 210);
    return plant;
}

// A tuft: thin tapering blades fanned around one direction, no stem.
Plant make_grass_tuft(const PlantClassSpec& spec, double px_per_mm, Rng& rng)
{
    Plant plant;
    plant.plant_class = PlantClass::Weed;
    plant.shape = PlantShape::grass_tuft;
    const double length_px = rng.uniform(spec.radius_mm.lo, spec.radius_mm.hi) * px_per_mm;
    const int count = rng.uniform_int(spec.leaves.lo, spec.leaves.hi);
    const double heading = rng.uniform(0, 2 * kPi);
    for (int i = 0; i < count; ++i) {
        LeafParams blade;
        blade.shape = BladeShape::linear;
        blade.angle_rad = heading + rng.uniform(-1.3, 1.3);
        blade.length_px = length_px * rng.uniform(0.5, 1.0);
        blade.petiole_half_px = rng.uniform(0.5, 1.1) * px_per_mm;
        blade.bend = rng.uniform(-0.25, 0.25);
        blade.shade = rng.uniform(0.85, 1.1);
        blade.nir_shift = rng.uniform(-10, 10);
        plant.leaves.push_back(blade);
    }
    plant.crown_radius_px = 0.8 * px_per_mm;
    plant.bgr = plant_colour_bgr(PlantClass::Weed, PlantShape::grass_tuft, rng);
    plant.nir = rng.uniform(175, 200);
    return plant;
}

namespace {

// Random stem positions inside the image, keeping a gap to every placed
// plant (or, with spec.overlap, letting their extents overlap that much);
// after every 50 failures the plant shrinks by 10 %. Stems stay inside the
// image (so every plant is in the ground truth) while leaves may leave it.
bool place_plant(Plant& plant, const std::vector<Plant>& placed, const std::vector<double>& placed_extent_px,
                 cv::Size size, double gap_px, double overlap, Rng& rng, double& extent_px)
{
    constexpr int kAttempts = 500;
    extent_px = plant_extent_px(plant);
    for (int attempt = 1; attempt <= kAttempts; ++attempt) {
        const cv::Point2d stem{rng.uniform(0, size.width - 1), rng.uniform(0, size.height - 1)};
        bool free = true;
        for (std::size_t i = 0; i < placed.size() && free; ++i) {
            const cv::Point2d d = stem - placed[i].stem_px;
            free = std::hypot(d.x, d.y) >= (extent_px + placed_extent_px[i]) * (1 - overlap) + gap_px;
        }
        if (free) {
            plant.stem_px = stem;
            return true;
        }
        if (attempt % 50 == 0) {
            scale_plant(plant, 0.9);
            extent_px = plant_extent_px(plant);
        }
    }
    return false;
}

}  // namespace

std::vector<Plant> make_layout(const PresetSpec& spec, cv::Size size, double px_per_mm, Rng& rng)
{
    const int crops = rng.uniform_int(spec.crop.count.lo, spec.crop.count.hi);
    const int weeds = rng.uniform_int(spec.weed.count.lo, spec.weed.count.hi);
    const int tufts = rng.uniform_int(spec.grass.count.lo, spec.grass.count.hi);
    std::vector<Plant> plants;
    std::vector<double> extents_px;
    const double gap_px = 2.0 * px_per_mm;
    // Crops first: the largest find room before the field fills up.
    for (int i = 0; i < crops + weeds + tufts; ++i) {
        Plant plant = i < crops           ? make_rosette(PlantClass::Crop, spec.crop, px_per_mm, rng)
                      : i < crops + weeds ? make_rosette(PlantClass::Weed, spec.weed, px_per_mm, rng)
                                          : make_grass_tuft(spec.grass, px_per_mm, rng);
        double extent_px = 0;
        if (place_plant(plant, plants, extents_px, size, gap_px, spec.overlap, rng, extent_px)) {
            plants.push_back(std::move(plant));
            extents_px.push_back(extent_px);
        }
    }
    return plants;
}

}  // namespace stemd::synth
