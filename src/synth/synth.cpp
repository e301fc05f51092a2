// Synthetic field frames. Outline of one frame:
//   1. soil: multi-scale value noise, clods and stones (colour + NIR);
//   2. layout: plants drawn as parameters, placed without overlap;
//   3. plants: each leaf (and crown, grass blade) is one anti-aliased layer
//      composited over the image, with its hard fill going into the mask;
//      fragmentation cuts gaps and holes out of both;
//   4. sensor: a light blur on colour and NIR (not the mask), then noise.
// Every random number comes from our own splitmix64 streams keyed on
// (seed, preset, frame, purpose), and is turned into numbers by integer or
// IEEE-exact arithmetic, so frames are byte-identical across runs. Separate
// streams keep e.g. the layout unchanged when only the fragmentation changes.
#include "stemd/synth/synth.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace stemd::synth {
namespace {

constexpr double kPi = std::numbers::pi;

// ---------------------------------------------------------------- random

std::uint64_t splitmix64(std::uint64_t& state)
{
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

// Combines two words so that nearby inputs give unrelated outputs.
std::uint64_t mix(std::uint64_t a, std::uint64_t b)
{
    std::uint64_t state = a;
    state = splitmix64(state) ^ b;
    return splitmix64(state);
}

class Rng {
public:
    explicit Rng(std::uint64_t seed) : state_(seed) {}
    std::uint64_t bits() { return splitmix64(state_); }
    // [0, 1) from the top 53 bits: exact, the same everywhere.
    double uniform() { return static_cast<double>(bits() >> 11) * 0x1.0p-53; }
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    // Inclusive; the multiply-shift bias (< 2^-32) does not matter here.
    int uniform_int(int lo, int hi)
    {
        const auto n = static_cast<std::uint64_t>(hi - lo + 1);
        return lo + static_cast<int>(((bits() >> 32) * n) >> 32);
    }
    bool chance(double p) { return uniform() < p; }

private:
    std::uint64_t state_;
};

// New streams go at the end: the others' numbers key every preset's bytes.
enum class Stream : std::uint64_t { layout = 1, soil, fragments, sensor, camera };

Rng make_stream(const Options& options, int frame_index, Stream stream)
{
    std::uint64_t key = mix(options.seed, static_cast<std::uint64_t>(options.preset) + 1);
    key = mix(key, static_cast<std::uint64_t>(frame_index));
    return Rng(mix(key, static_cast<std::uint64_t>(stream)));
}

// ---------------------------------------------------------------- presets

struct Range {
    double lo = 0, hi = 0;
};
struct IntRange {
    int lo = 0, hi = 0;
};
struct PlantClassSpec {
    IntRange count;
    Range radius_mm;   // stem to tip of the longest leaf (grass: longest blade)
    IntRange leaves;   // grass: blades per tuft
};
struct PresetSpec {
    PlantClassSpec crop, weed, grass;
    double fragmentation = 0;
    double soil_brightness = 1;   // times the soil's base colour
    double clods_per_m2 = 500;
    double stones_per_m2 = 250;
    bool real_camera = false;     // exposure, colour cast, vignetting, fringes, gain noise
};

// Counts are per frame (the paper's field of view is ~428 x 319 mm); plants
// that do not fit are shrunk, see place_plant().
PresetSpec preset_spec(Preset preset)
{
    switch (preset) {
    case Preset::early:
        return {.crop = {{4, 7}, {12, 25}, {2, 4}}, .weed = {{6, 12}, {3, 8}, {2, 4}}, .grass = {}, .fragmentation = 0};
    case Preset::late:
        return {.crop = {{2, 4}, {35, 70}, {4, 8}}, .weed = {{2, 5}, {8, 20}, {2, 4}}, .grass = {}, .fragmentation = 0};
    case Preset::seedling:
        return {.crop = {{3, 4}, {14, 24}, {2, 4}},
                .weed = {{3, 8}, {3, 8}, {2, 4}},
                .grass = {},
                .fragmentation = 0,
                .soil_brightness = 0.6,
                .clods_per_m2 = 1500,
                .stones_per_m2 = 120,
                .real_camera = true};
    case Preset::dense:
        break;
    }
    return {.crop = {{6, 10}, {25, 50}, {4, 7}},
            .weed = {{5, 10}, {6, 15}, {2, 4}},
            .grass = {{3, 6}, {25, 60}, {5, 10}},
            .fragmentation = 0.3};
}

// ---------------------------------------------------------------- geometry

using Polygon = std::vector<cv::Point2d>;

enum class PlantKind { crop, weed, grass };
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
    PlantKind kind = PlantKind::crop;
    cv::Point2d stem_px;
    double crown_radius_px = 0;
    std::vector<LeafParams> leaves;
    cv::Vec3d bgr;   // base colour
    double nir = 0;
};

cv::Point2d direction(const LeafParams& leaf) { return {std::cos(leaf.angle_rad), std::sin(leaf.angle_rad)}; }
cv::Point2d perpendicular(cv::Point2d v) { return {-v.y, v.x}; }
cv::Point2d unit(cv::Point2d v) { return v * (1.0 / std::hypot(v.x, v.y)); }

cv::Point2d centre_point(const LeafParams& leaf, double s)
{
    const double t = std::max(s, 0.0) / leaf.length_px;
    const cv::Point2d d = direction(leaf);
    return d * s + perpendicular(d) * (leaf.bend * leaf.length_px * t * t);
}

cv::Point2d centre_normal(const LeafParams& leaf, double s)
{
    const double t = std::max(s, 0.0) / leaf.length_px;
    const cv::Point2d d = direction(leaf);
    return perpendicular(unit(d + perpendicular(d) * (2 * leaf.bend * t)));
}

double half_width(const LeafParams& leaf, double s)
{
    if (leaf.shape == BladeShape::linear)
        return leaf.petiole_half_px * std::clamp(1 - s / leaf.length_px, 0.0, 1.0);
    if (s < leaf.petiole_length_px)
        return leaf.petiole_half_px;
    const double t = (s - leaf.petiole_length_px) / (leaf.length_px - leaf.petiole_length_px);
    // sin(pi t^a) peaks at t = peak_t when peak_t^a = 1/2.
    const double a = std::log(0.5) / std::log(leaf.peak_t);
    const double blade = leaf.blade_half_px * std::sin(kPi * std::pow(t, a));
    return t < 0.5 ? std::max(blade, leaf.petiole_half_px) : blade;
}

// Starts slightly behind the stem so that the petioles cover it.
double leaf_start(const LeafParams& leaf) { return -leaf.petiole_half_px; }

Polygon leaf_outline(const LeafParams& leaf)
{
    constexpr int kSamples = 36;
    const double s0 = leaf_start(leaf);
    Polygon left, right;
    for (int i = 0; i <= kSamples; ++i) {
        const double s = s0 + (leaf.length_px - s0) * i / kSamples;
        const cv::Point2d c = centre_point(leaf, s);
        const cv::Point2d n = centre_normal(leaf, s) * half_width(leaf, s);
        left.push_back(c + n);
        right.push_back(c - n);
    }
    left.insert(left.end(), right.rbegin(), right.rend());
    return left;
}

Polygon circle_polygon(cv::Point2d centre, double radius_x, double radius_y, double angle_rad, int vertices)
{
    Polygon poly;
    const cv::Point2d u{std::cos(angle_rad), std::sin(angle_rad)};
    for (int i = 0; i < vertices; ++i) {
        const double a = 2 * kPi * i / vertices;
        poly.push_back(centre + u * (radius_x * std::cos(a)) + perpendicular(u) * (radius_y * std::sin(a)));
    }
    return poly;
}

// Quadrilateral across the centreline at s: `along` wide along the leaf,
// from `from` to `to` (signed distances from the centreline, px).
Polygon cross_band(const LeafParams& leaf, cv::Point2d stem, double s, double along, double from, double to)
{
    const cv::Point2d a = stem + centre_point(leaf, s - along / 2);
    const cv::Point2d b = stem + centre_point(leaf, s + along / 2);
    const cv::Point2d na = centre_normal(leaf, s - along / 2), nb = centre_normal(leaf, s + along / 2);
    return {a + na * from, b + nb * from, b + nb * to, a + na * to};
}

double plant_extent_px(const Plant& plant)
{
    double extent = plant.crown_radius_px;
    for (const LeafParams& leaf : plant.leaves)
        for (const cv::Point2d& p : leaf_outline(leaf))
            extent = std::max(extent, std::hypot(p.x, p.y));
    return extent;
}

void scale_plant(Plant& plant, double factor)
{
    plant.crown_radius_px *= factor;
    for (LeafParams& leaf : plant.leaves) {
        leaf.length_px *= factor;
        leaf.petiole_length_px *= factor;
        leaf.petiole_half_px *= factor;
        leaf.blade_half_px *= factor;
    }
}

// ---------------------------------------------------------------- plants

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

cv::Vec3d plant_colour_bgr(PlantKind kind, Rng& rng)
{
    switch (kind) {
    case PlantKind::crop:   // sugar beet: medium green
        return {rng.uniform(35, 60), rng.uniform(110, 145), rng.uniform(55, 85)};
    case PlantKind::weed:   // yellowish or dark bluish green, to differ from the crop
        if (rng.chance(0.5))
            return {rng.uniform(30, 50), rng.uniform(120, 160), rng.uniform(80, 110)};
        return {rng.uniform(55, 75), rng.uniform(100, 125), rng.uniform(40, 60)};
    case PlantKind::grass:
        break;
    }
    return {rng.uniform(40, 60), rng.uniform(130, 165), rng.uniform(95, 125)};
}

LeafParams rosette_leaf(PlantKind kind, double angle_rad, double length_px, double px_per_mm, Rng& rng)
{
    const bool crop = kind == PlantKind::crop;
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

Plant make_rosette(PlantKind kind, const PlantClassSpec& spec, double px_per_mm, Rng& rng)
{
    Plant plant;
    plant.kind = kind;
    const double radius_px = rng.uniform(spec.radius_mm.lo, spec.radius_mm.hi) * px_per_mm;
    const int count = rng.uniform_int(spec.leaves.lo, spec.leaves.hi);
    const std::vector<double> angles = leaf_angles_rad(count, rng);
    const std::vector<double> lengths = leaf_lengths_px(count, radius_px, rng);
    for (int i = 0; i < count; ++i)
        plant.leaves.push_back(rosette_leaf(kind, angles[i], lengths[i], px_per_mm, rng));
    const double crown_mm = kind == PlantKind::crop ? rng.uniform(1.0, 2.0) : rng.uniform(0.4, 0.8);
    plant.crown_radius_px = std::min(crown_mm * px_per_mm, 0.2 * radius_px);
    plant.bgr = plant_colour_bgr(kind, rng);
    plant.nir = kind == PlantKind::crop ? rng.uniform(190, 220) : rng.uniform(180, 210);
    return plant;
}

// A tuft: thin tapering blades fanned around one direction, no stem.
Plant make_grass_tuft(const PlantClassSpec& spec, double px_per_mm, Rng& rng)
{
    Plant plant;
    plant.kind = PlantKind::grass;
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
    plant.bgr = plant_colour_bgr(PlantKind::grass, rng);
    plant.nir = rng.uniform(175, 200);
    return plant;
}

// Random stem positions inside the image, keeping a gap to every placed
// plant; after every 50 failures the plant shrinks by 10 %. Stems stay
// inside the image (so every plant is in the ground truth) while leaves may
// leave it.
bool place_plant(Plant& plant, const std::vector<Plant>& placed, const std::vector<double>& placed_extent_px,
                 cv::Size size, double gap_px, Rng& rng, double& extent_px)
{
    constexpr int kAttempts = 500;
    extent_px = plant_extent_px(plant);
    for (int attempt = 1; attempt <= kAttempts; ++attempt) {
        const cv::Point2d stem{rng.uniform(0, size.width - 1), rng.uniform(0, size.height - 1)};
        bool free = true;
        for (std::size_t i = 0; i < placed.size() && free; ++i) {
            const cv::Point2d d = stem - placed[i].stem_px;
            free = std::hypot(d.x, d.y) >= extent_px + placed_extent_px[i] + gap_px;
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
        Plant plant = i < crops           ? make_rosette(PlantKind::crop, spec.crop, px_per_mm, rng)
                      : i < crops + weeds ? make_rosette(PlantKind::weed, spec.weed, px_per_mm, rng)
                                          : make_grass_tuft(spec.grass, px_per_mm, rng);
        double extent_px = 0;
        if (place_plant(plant, plants, extents_px, size, gap_px, rng, extent_px)) {
            plants.push_back(std::move(plant));
            extents_px.push_back(extent_px);
        }
    }
    return plants;
}

// ---------------------------------------------------------------- soil

// Smoothed value noise: a random grid of cell_px, bilinearly interpolated
// with a smoothstep weight, added to `field` times `amplitude`. Our own
// interpolation (not cv::resize) keeps it bit-exact on any CPU.
void add_value_noise(std::vector<float>& field, cv::Size size, double cell_px, float amplitude, Rng& rng)
{
    cell_px = std::max(cell_px, 2.0);
    const int grid_w = static_cast<int>((size.width - 1) / cell_px) + 2;
    const int grid_h = static_cast<int>((size.height - 1) / cell_px) + 2;
    std::vector<float> grid(static_cast<std::size_t>(grid_w) * grid_h);
    for (float& g : grid)
        g = static_cast<float>(rng.uniform(-1, 1));
    auto smooth = [](double f) { return static_cast<float>(f * f * (3 - 2 * f)); };
    std::vector<int> ix(size.width);
    std::vector<float> fx(size.width);
    for (int x = 0; x < size.width; ++x) {
        ix[x] = static_cast<int>(x / cell_px);
        fx[x] = smooth(x / cell_px - ix[x]);
    }
    std::vector<float> row(grid_w);
    for (int y = 0; y < size.height; ++y) {
        const int iy = static_cast<int>(y / cell_px);
        const float fy = smooth(y / cell_px - iy);
        for (int j = 0; j < grid_w; ++j)
            row[j] = grid[iy * grid_w + j] * (1 - fy) + grid[(iy + 1) * grid_w + j] * fy;
        float* out = field.data() + static_cast<std::size_t>(y) * size.width;
        for (int x = 0; x < size.width; ++x)
            out[x] += amplitude * (row[ix[x]] * (1 - fx[x]) + row[ix[x] + 1] * fx[x]);
    }
}

void render_soil_texture(cv::Mat& bgr, cv::Mat& nir, double px_per_mm, double brightness, Rng& rng)
{
    const cv::Size size = bgr.size();
    const std::size_t n = static_cast<std::size_t>(size.area());
    // Brightness at several scales (lumps to grains), and moisture patches.
    std::vector<float> light(n, 0.0f), moisture(n, 0.0f);
    constexpr std::array<double, 5> kCellMm{45, 15, 5, 1.6, 0.7};
    constexpr std::array<float, 5> kAmplitude{0.25f, 0.2f, 0.2f, 0.18f, 0.12f};
    for (std::size_t i = 0; i < kCellMm.size(); ++i)
        add_value_noise(light, size, kCellMm[i] * px_per_mm, kAmplitude[i], rng);
    add_value_noise(moisture, size, 80 * px_per_mm, 1.0f, rng);
    const cv::Vec3d base = cv::Vec3d{rng.uniform(55, 70), rng.uniform(85, 100), rng.uniform(115, 135)} * brightness;
    for (int y = 0; y < size.height; ++y) {
        auto* colour = bgr.ptr<cv::Vec3b>(y);
        std::uint8_t* near_infrared = nir.ptr<std::uint8_t>(y);
        for (int x = 0; x < size.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * size.width + x;
            const double l = 1 + 0.22 * light[i];
            const double m = 0.5 + 0.5 * moisture[i];   // wet soil: darker, a little redder
            colour[x] = cv::Vec3b(cv::saturate_cast<std::uint8_t>(base[0] * l * (1 - 0.25 * m)),
                                  cv::saturate_cast<std::uint8_t>(base[1] * l * (1 - 0.2 * m)),
                                  cv::saturate_cast<std::uint8_t>(base[2] * l * (1 - 0.15 * m)));
            near_infrared[x] = cv::saturate_cast<std::uint8_t>(std::clamp(80 + 22 * light[i] - 12 * m, 50.0, 110.0));
        }
    }
}

constexpr int kShift = 4;   // sub-pixel bits for OpenCV drawing
constexpr double kFixedOne = 1 << kShift;

std::vector<cv::Point> to_fixed(const Polygon& poly, cv::Point2d origin)
{
    std::vector<cv::Point> fixed;
    fixed.reserve(poly.size());
    for (const cv::Point2d& p : poly)
        fixed.emplace_back(static_cast<int>(std::lround((p.x - origin.x) * kFixedOne)),
                           static_cast<int>(std::lround((p.y - origin.y) * kFixedOne)));
    return fixed;
}

void fill(cv::Mat& image, const Polygon& poly, cv::Point2d origin, const cv::Scalar& value, int line_type)
{
    const std::vector<std::vector<cv::Point>> polys{to_fixed(poly, origin)};
    cv::fillPoly(image, polys, value, line_type, kShift);
}

// Dark clods with a lit top-left rim, and greyish stones; counts scale
// with the ground area so the texture density does not depend on size.
void render_clods_and_stones(cv::Mat& bgr, cv::Mat& nir, double px_per_mm, double clods_per_m2, double stones_per_m2,
                             Rng& rng)
{
    const double area_mm2 = bgr.size().area() / (px_per_mm * px_per_mm);
    const int clods = static_cast<int>(area_mm2 * clods_per_m2 / 1e6);
    const int stones = static_cast<int>(area_mm2 * stones_per_m2 / 1e6);
    const cv::Size size = bgr.size();
    for (int i = 0; i < clods + stones; ++i) {
        const bool stone = i >= clods;
        const cv::Point2d centre{rng.uniform(0, size.width - 1), rng.uniform(0, size.height - 1)};
        const double radius_px = (stone ? rng.uniform(1, 5) : rng.uniform(1, 4.5)) * px_per_mm;
        const double aspect = rng.uniform(0.5, 1.0), angle_rad = rng.uniform(0, kPi);
        const Polygon body = circle_polygon(centre, radius_px, radius_px * aspect, angle_rad, 24);
        cv::Scalar colour, nir_value;
        if (stone) {
            const double grey = rng.uniform(110, 170);
            colour = {grey * 0.92, grey * 0.97, grey};
            nir_value = cv::Scalar(70 + 0.25 * grey);
        } else {
            const double dark = rng.uniform(0.55, 0.8);
            colour = {65 * dark, 88 * dark, 112 * dark};
            nir_value = cv::Scalar(rng.uniform(50, 70));
        }
        fill(bgr, body, {0, 0}, colour, cv::LINE_AA);
        fill(nir, body, {0, 0}, nir_value, cv::LINE_AA);
        const cv::Point2d lit = centre - cv::Point2d(0.25, 0.25) * radius_px;
        fill(bgr, circle_polygon(lit, radius_px * 0.6, radius_px * 0.6 * aspect, angle_rad, 16), {0, 0},
             colour * 1.15, cv::LINE_AA);
    }
}

// ---------------------------------------------------------------- plant rendering

struct Stroke {
    Polygon points;
    int thickness_px = 1;
    cv::Vec3d gain{1, 1, 1};   // multiplies the layer colour per channel
    bool closed = false;
};

// One leaf, grass blade or crown: alpha-composited over the image, its hard
// fill (minus cuts) added to the plant's mask.
struct Layer {
    Polygon outline;
    std::vector<Polygon> cuts;
    std::vector<Stroke> strokes;
    cv::Vec3d bgr;
    double nir = 0;
    // Brightness ramps along the leaf: `ramp_gain` from base to tip.
    cv::Point2d ramp_origin, ramp_direction;
    double ramp_length_px = 1, ramp_gain = 0;
};

struct Canvas {
    cv::Mat bgr, nir, mask;
    std::vector<float> leaf_texture;   // per pixel, about -1..1: blotches on the leaves
    cv::Mat plant_class;               // optional (strips): PixelClass per pixel
};

cv::Rect bounding_box(const Polygon& poly, const cv::Rect& clip)
{
    double x0 = poly[0].x, x1 = x0, y0 = poly[0].y, y1 = y0;
    for (const cv::Point2d& p : poly) {
        x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
        y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
    }
    const cv::Point tl(static_cast<int>(std::floor(x0)) - 2, static_cast<int>(std::floor(y0)) - 2);
    const cv::Point br(static_cast<int>(std::ceil(x1)) + 3, static_cast<int>(std::ceil(y1)) + 3);
    return cv::Rect(tl, br) & clip;
}

void composite(Canvas& canvas, const cv::Rect& box, const cv::Mat& alpha, const cv::Mat& colour, const Layer& layer)
{
    for (int y = 0; y < box.height; ++y) {
        const std::uint8_t* a = alpha.ptr<std::uint8_t>(y);
        const auto* c = colour.ptr<cv::Vec3b>(y);
        auto* dst = canvas.bgr.ptr<cv::Vec3b>(box.y + y) + box.x;
        std::uint8_t* near_infrared = canvas.nir.ptr<std::uint8_t>(box.y + y) + box.x;
        for (int x = 0; x < box.width; ++x) {
            if (a[x] == 0)
                continue;
            const cv::Point2d p = cv::Point2d(box.x + x, box.y + y) - layer.ramp_origin;
            const double u = std::clamp(p.dot(layer.ramp_direction) / layer.ramp_length_px, 0.0, 1.0);
            const float texture = canvas.leaf_texture[static_cast<std::size_t>(box.y + y) * canvas.bgr.cols + box.x + x];
            const double gain = (1 + layer.ramp_gain * (u - 0.5)) * (1 + 0.08 * texture);
            const int w = a[x];
            for (int ch = 0; ch < 3; ++ch) {
                const int v = cv::saturate_cast<std::uint8_t>(c[x][ch] * gain);
                dst[x][ch] = static_cast<std::uint8_t>((dst[x][ch] * (255 - w) + v * w + 127) / 255);
            }
            const int n = cv::saturate_cast<std::uint8_t>(layer.nir * (0.95 + 0.1 * u));
            near_infrared[x] = static_cast<std::uint8_t>((near_infrared[x] * (255 - w) + n * w + 127) / 255);
        }
    }
}

// Draws `layer` inside `plant_box` and ORs its hard fill into plant_mask
// (which covers plant_box).
void draw_layer(Canvas& canvas, const cv::Rect& plant_box, cv::Mat& plant_mask, const Layer& layer)
{
    const cv::Rect box = bounding_box(layer.outline, plant_box);
    if (box.empty())
        return;
    const cv::Point2d origin(box.x, box.y);
    cv::Mat alpha = cv::Mat::zeros(box.size(), CV_8UC1), hard = cv::Mat::zeros(box.size(), CV_8UC1);
    fill(alpha, layer.outline, origin, cv::Scalar(255), cv::LINE_AA);
    fill(hard, layer.outline, origin, cv::Scalar(255), cv::LINE_8);
    for (const Polygon& cut : layer.cuts) {
        fill(alpha, cut, origin, cv::Scalar(0), cv::LINE_AA);
        fill(hard, cut, origin, cv::Scalar(0), cv::LINE_8);
    }
    cv::Mat colour(box.size(), CV_8UC3, cv::Scalar(layer.bgr[0], layer.bgr[1], layer.bgr[2]));
    for (const Stroke& stroke : layer.strokes) {
        const cv::Vec3d c = layer.bgr.mul(stroke.gain);
        const std::vector<std::vector<cv::Point>> lines{to_fixed(stroke.points, origin)};
        cv::polylines(colour, lines, stroke.closed, cv::Scalar(c[0], c[1], c[2]), stroke.thickness_px, cv::LINE_AA,
                      kShift);
    }
    composite(canvas, box, alpha, colour, layer);
    cv::Mat target = plant_mask(box - plant_box.tl());
    cv::bitwise_or(target, hard, target);
}

// Fragmentation of one leaf: gaps across the petiole, a tear into the
// blade, holes in the blade; none near the stem, so the stem stays on the
// mask. `fragmentation` scales how likely and how many.
std::vector<Polygon> leaf_cuts(const LeafParams& leaf, cv::Point2d stem, double fragmentation, double px_per_mm,
                               Rng& rng)
{
    std::vector<Polygon> cuts;
    if (fragmentation <= 0)
        return cuts;
    const double margin_px = 1.5;
    if (leaf.petiole_length_px > 2 * px_per_mm && rng.chance(fragmentation)) {
        const double s = leaf.petiole_length_px * rng.uniform(0.35, 0.85);
        const double across = leaf.petiole_half_px + margin_px;
        cuts.push_back(cross_band(leaf, stem, s, rng.uniform(0.4, 1.0) * px_per_mm, -across, across));
    }
    const double blade_px = leaf.length_px - leaf.petiole_length_px;
    if (blade_px < 3 * px_per_mm)
        return cuts;
    if (rng.chance(fragmentation)) {   // a tear from one edge into the blade
        const double s = leaf.petiole_length_px + blade_px * rng.uniform(0.2, 0.8);
        const double h = half_width(leaf, s), side = rng.chance(0.5) ? 1.0 : -1.0;
        const double depth = rng.uniform(0.4, 0.8) * 2 * h;
        cuts.push_back(cross_band(leaf, stem, s, rng.uniform(0.3, 0.7) * px_per_mm, side * (h + margin_px),
                                  side * (h - depth)));
    }
    const double blade_area_mm2 = blade_px * leaf.blade_half_px * 1.3 / (px_per_mm * px_per_mm);
    const int holes = static_cast<int>(fragmentation * blade_area_mm2 / 60 + rng.uniform());
    for (int i = 0; i < holes; ++i) {
        const double s = leaf.petiole_length_px + blade_px * rng.uniform(0.1, 0.9);
        const cv::Point2d centre =
            stem + centre_point(leaf, s) + centre_normal(leaf, s) * (half_width(leaf, s) * rng.uniform(-0.8, 0.8));
        const double r_px = rng.uniform(0.4, 1.2) * px_per_mm;
        cuts.push_back(circle_polygon(centre, r_px, r_px * rng.uniform(0.6, 1.0), rng.uniform(0, kPi), 10));
    }
    return cuts;
}

std::vector<Polygon> grass_cuts(const LeafParams& blade, cv::Point2d stem, double fragmentation, double px_per_mm,
                                Rng& rng)
{
    std::vector<Polygon> cuts;
    for (int i = 0; i < 2 && rng.chance(fragmentation * (i == 0 ? 1.0 : 0.5)); ++i) {
        const double s = blade.length_px * rng.uniform(0.2, 0.8);
        const double across = blade.petiole_half_px + 1.5;
        cuts.push_back(cross_band(blade, stem, s, rng.uniform(0.4, 1.0) * px_per_mm, -across, across));
    }
    return cuts;
}

Polygon translated(Polygon poly, cv::Point2d offset)
{
    for (cv::Point2d& p : poly)
        p += offset;
    return poly;
}

// Pale petiole, light midrib and a dark rim on rosette leaves large enough
// to show them.
std::vector<Stroke> leaf_strokes(const LeafParams& leaf, cv::Point2d stem, const Polygon& outline, double px_per_mm)
{
    std::vector<Stroke> strokes;
    if (leaf.shape == BladeShape::linear)
        return strokes;
    auto axis = [&](double s0, double s1) {
        Polygon pts;
        for (int i = 0; i <= 8; ++i)
            pts.push_back(stem + centre_point(leaf, s0 + (s1 - s0) * i / 8));
        return pts;
    };
    const int petiole_width_px = std::max(1, static_cast<int>(std::lround(2 * leaf.petiole_half_px)));
    strokes.push_back({axis(0, leaf.petiole_length_px), petiole_width_px, {1.0, 1.12, 1.25}, false});
    if (leaf.length_px - leaf.petiole_length_px > 6 * px_per_mm) {
        strokes.push_back({axis(leaf.petiole_length_px, leaf.petiole_length_px + 0.85 * (leaf.length_px - leaf.petiole_length_px)), 1,
                           {1.05, 1.15, 1.2}, false});
        strokes.push_back({outline, 1, {0.75, 0.75, 0.75}, true});
    }
    return strokes;
}

Layer leaf_layer(const Plant& plant, const LeafParams& leaf, double fragmentation, double px_per_mm, Rng& rng)
{
    Layer layer;
    layer.outline = translated(leaf_outline(leaf), plant.stem_px);
    layer.cuts = leaf.shape == BladeShape::linear ? grass_cuts(leaf, plant.stem_px, fragmentation, px_per_mm, rng)
                                                  : leaf_cuts(leaf, plant.stem_px, fragmentation, px_per_mm, rng);
    layer.strokes = leaf_strokes(leaf, plant.stem_px, layer.outline, px_per_mm);
    layer.bgr = plant.bgr * leaf.shade;
    layer.nir = plant.nir + leaf.nir_shift;
    layer.ramp_origin = plant.stem_px;
    layer.ramp_direction = direction(leaf);
    layer.ramp_length_px = leaf.length_px;
    layer.ramp_gain = 0.2;
    return layer;
}

Layer crown_layer(const Plant& plant)
{
    Layer layer;
    layer.outline = circle_polygon(plant.stem_px, plant.crown_radius_px, plant.crown_radius_px, 0, 16);
    layer.bgr = plant.bgr * 0.9;
    layer.nir = plant.nir;
    layer.ramp_origin = plant.stem_px;
    layer.ramp_direction = {1, 0};
    return layer;
}

// Draws a plant (longest leaves first: the young short ones sit on top,
// then the crown) and returns its mask pixels as ground truth; with
// mask_out, also its own mask (over *box_out). A canvas with a class map
// gets the plant's class on its mask pixels.
GroundTruthStem render_plant(Canvas& canvas, const Plant& plant, double fragmentation, double px_per_mm, Rng& rng,
                             cv::Mat* mask_out = nullptr, cv::Rect* box_out = nullptr)
{
    const double extent_px = plant_extent_px(plant);
    const cv::Point2d reach(extent_px + 3, extent_px + 3);   // + anti-aliasing
    const cv::Rect image(0, 0, canvas.bgr.cols, canvas.bgr.rows);
    const cv::Rect plant_box = bounding_box({plant.stem_px - reach, plant.stem_px + reach}, image);
    cv::Mat plant_mask = cv::Mat::zeros(plant_box.size(), CV_8UC1);
    std::vector<LeafParams> leaves = plant.leaves;
    std::stable_sort(leaves.begin(), leaves.end(),
                     [](const LeafParams& a, const LeafParams& b) { return a.length_px > b.length_px; });
    for (const LeafParams& leaf : leaves)
        draw_layer(canvas, plant_box, plant_mask, leaf_layer(plant, leaf, fragmentation, px_per_mm, rng));
    draw_layer(canvas, plant_box, plant_mask, crown_layer(plant));
    cv::Mat target = canvas.mask(plant_box);
    cv::bitwise_or(target, plant_mask, target);
    if (!canvas.plant_class.empty()) {
        const PixelClass value = plant.kind == PlantKind::crop ? PixelClass::crop : PixelClass::weed;
        canvas.plant_class(plant_box).setTo(cv::Scalar(static_cast<int>(value)), plant_mask);
    }
    if (mask_out != nullptr && box_out != nullptr) {
        *mask_out = plant_mask;
        *box_out = plant_box;
    }

    GroundTruthStem gt;
    gt.x_px = plant.stem_px.x;
    gt.y_px = plant.stem_px.y;
    gt.kind = plant.kind == PlantKind::crop ? "crop" : "weed";
    gt.leaves = static_cast<int>(plant.leaves.size());
    gt.radius_mm = extent_px / px_per_mm;
    const cv::Moments m = cv::moments(plant_mask, true);
    gt.area_px = static_cast<int>(m.m00);
    if (m.m00 > 0) {
        gt.mass_x_px = plant_box.x + m.m10 / m.m00;
        gt.mass_y_px = plant_box.y + m.m01 / m.m00;
    }
    return gt;
}

// ---------------------------------------------------------------- sensor

// Approximately Gaussian noise from the sum of four random bytes (mean 510,
// standard deviation 147.8), in integers so it is exact everywhere.
void add_sensor_noise(cv::Mat& image, double sigma, Rng& rng)
{
    const std::int64_t scale_q16 = std::llround(sigma / 147.8 * 65536);
    std::uint64_t bits = 0;
    int bytes_left = 0;
    auto sample = [&] {
        if (bytes_left == 0)
            bits = rng.bits(), bytes_left = 8;
        int sum = 0;
        for (int i = 0; i < 4; ++i, bits >>= 8)
            sum += static_cast<int>(bits & 0xFF);
        bytes_left -= 4;
        return static_cast<int>(((sum - 510) * scale_q16 + (1 << 15)) >> 16);
    };
    const int values_per_row = image.cols * image.channels();
    for (int y = 0; y < image.rows; ++y) {
        std::uint8_t* row = image.ptr<std::uint8_t>(y);
        for (int i = 0; i < values_per_row; ++i)
            row[i] = cv::saturate_cast<std::uint8_t>(row[i] + sample());
    }
}

// A camera of its own: one exposure, colour saturation (a dull colour
// matrix, as on BoniRob's camera) and colour cast per frame,
// a radial vignetting falloff, red and blue planes one pixel off the green
// one horizontally (lateral chromatic aberration: coloured fringes at every
// edge), then sensor noise that grows as the gain lowers the signal.
void apply_real_camera(cv::Mat& bgr, cv::Mat& nir, Rng& rng)
{
    const double exposure = rng.uniform(0.55, 1.25);
    const double cast[3] = {rng.uniform(0.85, 1.15), rng.uniform(0.9, 1.1), rng.uniform(0.85, 1.15)};
    const double vignetting = rng.uniform(0.15, 0.35);
    const double saturation = rng.uniform(0.4, 0.7);
    const double cx = (bgr.cols - 1) / 2.0, cy = (bgr.rows - 1) / 2.0;
    const double r2_max = cx * cx + cy * cy;
    const cv::Mat source = bgr.clone();
    for (int y = 0; y < bgr.rows; ++y) {
        const auto* in = source.ptr<cv::Vec3b>(y);
        auto* out = bgr.ptr<cv::Vec3b>(y);
        std::uint8_t* near_infrared = nir.ptr<std::uint8_t>(y);
        for (int x = 0; x < bgr.cols; ++x) {
            const double r2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / r2_max;
            const double light = exposure * (1 - vignetting * r2);
            const int from_blue = std::min(x + 1, bgr.cols - 1), from_red = std::max(x - 1, 0);
            const double b = in[from_blue][0], g = in[x][1], r = in[from_red][2];
            const double grey = (b + g + r) / 3;
            auto channel = [&](double v, double gain) {
                return cv::saturate_cast<std::uint8_t>((grey + saturation * (v - grey)) * light * gain);
            };
            out[x] = cv::Vec3b(channel(b, cast[0]), channel(g, cast[1]), channel(r, cast[2]));
            near_infrared[x] = cv::saturate_cast<std::uint8_t>(near_infrared[x] * light);
        }
    }
    add_sensor_noise(bgr, 2.5 / std::sqrt(exposure), rng);
    add_sensor_noise(nir, 2.0 / std::sqrt(exposure), rng);
}

// The preset's camera: a real one, or only sensor noise.
void apply_camera(const PresetSpec& spec, cv::Mat& bgr, cv::Mat& nir, Rng camera, Rng sensor)
{
    if (spec.real_camera) {
        apply_real_camera(bgr, nir, camera);
        return;
    }
    add_sensor_noise(bgr, 2.5, sensor);
    add_sensor_noise(nir, 2.0, sensor);
}

void validate(const Options& options, int frame_index)
{
    if (options.width_px < 16 || options.height_px < 16 || options.width_px > 32768 || options.height_px > 32768)
        throw std::invalid_argument("synth: image size must be 16..32768 px");
    if (!(options.gsd_mm_per_px > 0 && options.gsd_mm_per_px <= 100))
        throw std::invalid_argument("synth: gsd_mm_per_px must be in (0, 100]");
    if (!(options.fragmentation <= 1))
        throw std::invalid_argument("synth: fragmentation must be <= 1 (< 0: preset default)");
    if (frame_index < 0)
        throw std::invalid_argument("synth: frame_index must be >= 0");
}

}  // namespace

std::optional<Preset> parse_preset(std::string_view name)
{
    for (const Preset p : {Preset::early, Preset::late, Preset::dense, Preset::seedling})
        if (name == to_string(p))
            return p;
    return std::nullopt;
}

std::string_view to_string(Preset preset)
{
    switch (preset) {
    case Preset::early: return "early";
    case Preset::late: return "late";
    case Preset::dense: return "dense";
    case Preset::seedling: return "seedling";
    }
    return "late";
}

Frame generate_frame(const Options& options, int frame_index)
{
    validate(options, frame_index);
    const PresetSpec spec = preset_spec(options.preset);
    const double fragmentation = options.fragmentation < 0 ? spec.fragmentation : options.fragmentation;
    const double px_per_mm = 1.0 / options.gsd_mm_per_px;
    const cv::Size size(options.width_px, options.height_px);

    Canvas canvas{cv::Mat(size, CV_8UC3), cv::Mat(size, CV_8UC1), cv::Mat::zeros(size, CV_8UC1), {}, {}};
    Rng soil = make_stream(options, frame_index, Stream::soil);
    render_soil_texture(canvas.bgr, canvas.nir, px_per_mm, spec.soil_brightness, soil);
    render_clods_and_stones(canvas.bgr, canvas.nir, px_per_mm, spec.clods_per_m2, spec.stones_per_m2, soil);
    canvas.leaf_texture.assign(static_cast<std::size_t>(size.area()), 0.0f);
    add_value_noise(canvas.leaf_texture, size, 3 * px_per_mm, 0.6f, soil);
    add_value_noise(canvas.leaf_texture, size, 1 * px_per_mm, 0.4f, soil);

    Rng layout = make_stream(options, frame_index, Stream::layout);
    Rng fragments = make_stream(options, frame_index, Stream::fragments);
    Frame frame;
    for (const Plant& plant : make_layout(spec, size, px_per_mm, layout)) {
        const GroundTruthStem gt = render_plant(canvas, plant, fragmentation, px_per_mm, fragments);
        const bool inside = gt.x_px >= 0 && gt.y_px >= 0 && gt.x_px <= size.width - 1 && gt.y_px <= size.height - 1;
        if (plant.kind != PlantKind::grass && inside)
            frame.stems.push_back(gt);
    }

    // Optics (a light blur; the mask stays sharp) then sensor noise.
    // GaussianBlur on 8-bit with the 3x3 [1 2 1] kernel is fixed-point.
    cv::GaussianBlur(canvas.bgr, canvas.bgr, cv::Size(3, 3), 0);
    cv::GaussianBlur(canvas.nir, canvas.nir, cv::Size(3, 3), 0);
    apply_camera(spec, canvas.bgr, canvas.nir, make_stream(options, frame_index, Stream::camera),
                 make_stream(options, frame_index, Stream::sensor));

    frame.bgr = canvas.bgr;
    frame.nir = canvas.nir;
    frame.mask = canvas.mask;
    return frame;
}

// ---------------------------------------------------------------- strips

namespace {

// Strip streams are keyed apart from generate_frame's ("STRIP" in ASCII).
Rng make_strip_stream(const StripOptions& options, int index, Stream stream)
{
    std::uint64_t key = mix(options.seed, static_cast<std::uint64_t>(options.preset) + 1);
    key = mix(key, 0x5354524950ull);
    key = mix(key, static_cast<std::uint64_t>(index));
    return Rng(mix(key, static_cast<std::uint64_t>(stream)));
}

void validate_strip(const StripOptions& o)
{
    validate(Options{.preset = o.preset,
                     .seed = o.seed,
                     .width_px = o.width_px,
                     .height_px = o.height_px,
                     .gsd_mm_per_px = o.gsd_mm_per_px,
                     .fragmentation = o.fragmentation},
             0);
    if (!(o.length_mm > 0 && o.length_mm <= 1e6))
        throw std::invalid_argument("synth: strip length_mm must be in (0, 1000000]");
    if (!(o.speed_kmh > 0 && o.speed_kmh <= 1000))
        throw std::invalid_argument("synth: strip speed_kmh must be in (0, 1000]");
    if (!(o.fps > 0 && o.fps <= 10000))
        throw std::invalid_argument("synth: strip fps must be in (0, 10000]");
}

double step_mm(const StripOptions& o) { return o.speed_kmh * 1e6 / 3600.0 / o.fps; }

// Frame k's odometer in canvas rows (whole pixels).
std::int64_t odom_rows(const StripOptions& o, int k)
{
    return std::llround(static_cast<double>(k) * step_mm(o) / o.gsd_mm_per_px);
}

struct StripLayoutPlant {
    Plant plant;
    double s_mm = 0, y_mm = 0, extent_mm = 0;
};

// Plants of `spec` along [lead_mm, lead_mm + length_mm): per block of one
// view length, the counts generate_frame draws per frame (a last, partial
// block keeps each plant with the probability of its fraction). A place is
// free when the stem is >= kStripMinStemSpacingMm from every other stem (or
// tuft base) and the plants do not overlap (extents + 2 mm), and its leaves
// stay ahead of the first view (s - extent >= view/2 + 10 mm). As in
// place_plant: 500 tries, shrinking by 10 % every 50.
std::vector<StripLayoutPlant> make_strip_layout(const StripOptions& o, const PresetSpec& spec, double lead_mm,
                                                double view_length_mm, double width_mm, Rng& rng)
{
    const double px_per_mm = 1.0 / o.gsd_mm_per_px;
    const double y_max = width_mm / 2 - kStripEdgeMarginMm;
    const double first_leaf_mm = view_length_mm / 2 + 10;
    const double gap_mm = 2.0;
    const double end_mm = lead_mm + o.length_mm;
    std::vector<StripLayoutPlant> placed;
    if (y_max < 0)
        return placed;   // narrower than the edge margins: no room for a stem
    double widest_mm = 0;   // the largest extent placed so far, to skip far plants quickly
    for (double block = lead_mm; block < end_mm; block += view_length_mm) {
        const double block_end = std::min(block + view_length_mm, end_mm);
        const double fraction = (block_end - block) / view_length_mm;
        const int crops = rng.uniform_int(spec.crop.count.lo, spec.crop.count.hi);
        const int weeds = rng.uniform_int(spec.weed.count.lo, spec.weed.count.hi);
        const int tufts = rng.uniform_int(spec.grass.count.lo, spec.grass.count.hi);
        for (int i = 0; i < crops + weeds + tufts; ++i) {
            StripLayoutPlant p;
            p.plant = i < crops           ? make_rosette(PlantKind::crop, spec.crop, px_per_mm, rng)
                      : i < crops + weeds ? make_rosette(PlantKind::weed, spec.weed, px_per_mm, rng)
                                          : make_grass_tuft(spec.grass, px_per_mm, rng);
            if (fraction < 1 && !rng.chance(fraction))
                continue;
            p.extent_mm = plant_extent_px(p.plant) / px_per_mm;
            bool found = false;
            for (int attempt = 1; attempt <= 500 && !found; ++attempt) {
                const double s = rng.uniform(block, block_end);
                const double y = rng.uniform(-y_max, y_max);
                bool free = s - p.extent_mm >= first_leaf_mm;
                const double reach = std::max(kStripMinStemSpacingMm, p.extent_mm + widest_mm + gap_mm);
                for (auto q = placed.rbegin(); q != placed.rend() && free; ++q) {
                    if (std::abs(q->s_mm - s) >= reach)
                        continue;
                    const double need = std::max(kStripMinStemSpacingMm, p.extent_mm + q->extent_mm + gap_mm);
                    free = std::hypot(q->s_mm - s, q->y_mm - y) >= need;
                }
                if (free) {
                    p.s_mm = s;
                    p.y_mm = y;
                    found = true;
                } else if (attempt % 50 == 0) {
                    scale_plant(p.plant, 0.9);
                    p.extent_mm = plant_extent_px(p.plant) / px_per_mm;
                }
            }
            if (found) {
                widest_mm = std::max(widest_mm, p.extent_mm);
                placed.push_back(std::move(p));
            }
        }
    }
    return placed;
}

}  // namespace

double Strip::odom_mm(int k) const
{
    return static_cast<double>(odom_rows(options, k)) * options.gsd_mm_per_px;
}

std::int64_t Strip::t_ns(int k) const
{
    return kStripT0Ns + static_cast<std::int64_t>(k) * std::llround(1e9 / options.fps);
}

int Strip::canvas_row(int k) const
{
    return static_cast<int>(odom_rows(options, frame_count - 1) - odom_rows(options, k));
}

cv::Point2d strip_pixel(const StripOptions& options, double s_mm, double y_mm, double odom_mm)
{
    const cv::Point2d c((options.width_px - 1) / 2.0, (options.height_px - 1) / 2.0);
    return {c.x - y_mm / options.gsd_mm_per_px, c.y - (s_mm - odom_mm) / options.gsd_mm_per_px};
}

Strip generate_strip(const StripOptions& options)
{
    validate_strip(options);
    const PresetSpec spec = preset_spec(options.preset);
    const double fragmentation = options.fragmentation < 0 ? spec.fragmentation : options.fragmentation;
    const double gsd = options.gsd_mm_per_px;
    const double px_per_mm = 1.0 / gsd;

    Strip strip;
    strip.options = options;
    strip.view_length_mm = options.height_px * gsd;
    strip.width_mm = options.width_px * gsd;
    const double largest_radius_mm =
        std::max({spec.crop.radius_mm.hi, spec.weed.radius_mm.hi, spec.grass.radius_mm.hi});
    strip.lead_mm = strip.view_length_mm / 2 + largest_radius_mm + 10;

    Rng layout_rng = make_strip_stream(options, 0, Stream::layout);
    const std::vector<StripLayoutPlant> layout =
        make_strip_layout(options, spec, strip.lead_mm, strip.view_length_mm, strip.width_mm, layout_rng);

    // Frames until every leaf is 10 mm past the view's trailing edge.
    double end_mm = 0;
    for (const StripLayoutPlant& p : layout)
        end_mm = std::max(end_mm, p.s_mm + p.extent_mm + strip.view_length_mm / 2 + 10);
    int last = std::max(0, static_cast<int>(std::min(end_mm / step_mm(options), 2e6)) - 2);
    while (last <= 1'000'000 && static_cast<double>(odom_rows(options, last)) * gsd < end_mm)
        ++last;
    if (last >= 1'000'000)
        throw std::invalid_argument("synth: strip needs more than 1000000 frames (too long or too slow)");
    strip.frame_count = last + 1;
    const std::int64_t last_rows = odom_rows(options, last);
    const std::int64_t rows = last_rows + options.height_px;
    if (rows * options.width_px > (std::int64_t{1} << 26))
        throw std::invalid_argument("synth: strip canvas above 2^26 px (too long for this width and gsd)");
    const double cy = (options.height_px - 1) / 2.0;
    strip.top_s_mm = (static_cast<double>(last_rows) + cy) * gsd;

    const cv::Size size(options.width_px, static_cast<int>(rows));
    Canvas canvas{cv::Mat(size, CV_8UC3), cv::Mat(size, CV_8UC1), cv::Mat::zeros(size, CV_8UC1), {},
                  cv::Mat::zeros(size, CV_8UC1)};
    Rng soil = make_strip_stream(options, 0, Stream::soil);
    render_soil_texture(canvas.bgr, canvas.nir, px_per_mm, spec.soil_brightness, soil);
    render_clods_and_stones(canvas.bgr, canvas.nir, px_per_mm, spec.clods_per_m2, spec.stones_per_m2, soil);
    canvas.leaf_texture.assign(static_cast<std::size_t>(size.area()), 0.0f);
    add_value_noise(canvas.leaf_texture, size, 3 * px_per_mm, 0.6f, soil);
    add_value_noise(canvas.leaf_texture, size, 1 * px_per_mm, 0.4f, soil);

    Rng fragments = make_strip_stream(options, 0, Stream::fragments);
    const double cx = (options.width_px - 1) / 2.0;
    std::vector<StripPlant> stemmed;
    for (const StripLayoutPlant& p : layout) {
        Plant plant = p.plant;
        plant.stem_px = {cx - p.y_mm * px_per_mm, (strip.top_s_mm - p.s_mm) * px_per_mm};
        StripPlant sp;
        const GroundTruthStem gt =
            render_plant(canvas, plant, fragmentation, px_per_mm, fragments, &sp.canvas_mask, &sp.canvas_box);
        if (plant.kind == PlantKind::grass) {
            ++strip.grass_tufts;
            continue;
        }
        sp.s_mm = p.s_mm;
        sp.y_mm = p.y_mm;
        sp.kind = gt.kind;
        sp.leaves = gt.leaves;
        sp.radius_mm = gt.radius_mm;
        stemmed.push_back(std::move(sp));
    }
    canvas.leaf_texture = {};
    std::stable_sort(stemmed.begin(), stemmed.end(),
                     [](const StripPlant& a, const StripPlant& b) { return a.s_mm < b.s_mm; });
    for (std::size_t i = 0; i < stemmed.size(); ++i)
        stemmed[i].id = static_cast<int>(i);
    strip.plants = std::move(stemmed);

    // Optics, as generate_frame; the sensor noise is per frame.
    cv::GaussianBlur(canvas.bgr, canvas.bgr, cv::Size(3, 3), 0);
    cv::GaussianBlur(canvas.nir, canvas.nir, cv::Size(3, 3), 0);
    strip.bgr = canvas.bgr;
    strip.nir = canvas.nir;
    strip.mask = canvas.mask;
    strip.plant_class = canvas.plant_class;
    return strip;
}

StripFrame render_strip_frame(const Strip& strip, int k)
{
    if (k < 0 || k >= strip.frame_count)
        throw std::out_of_range("synth: strip frame index out of range");
    const StripOptions& o = strip.options;
    const cv::Rect view(0, strip.canvas_row(k), o.width_px, o.height_px);
    StripFrame frame;
    frame.index = k;
    frame.t_ns = strip.t_ns(k);
    frame.odom_mm = strip.odom_mm(k);
    frame.bgr = strip.bgr(view).clone();
    frame.nir = strip.nir(view).clone();
    frame.mask = strip.mask(view).clone();
    frame.plant_class = strip.plant_class(view).clone();
    apply_camera(preset_spec(o.preset), frame.bgr, frame.nir, make_strip_stream(o, k, Stream::camera),
                 make_strip_stream(o, k, Stream::sensor));

    for (const StripPlant& p : strip.plants) {
        const cv::Point2d px = strip_pixel(o, p.s_mm, p.y_mm, frame.odom_mm);
        if (!(px.x >= 0 && px.y >= 0 && px.x <= o.width_px - 1 && px.y <= o.height_px - 1))
            continue;
        GroundTruthStem gt;
        gt.x_px = px.x;
        gt.y_px = px.y;
        gt.kind = p.kind;
        gt.leaves = p.leaves;
        gt.radius_mm = p.radius_mm;
        const cv::Rect part = p.canvas_box & view;
        if (!part.empty()) {
            const cv::Moments m = cv::moments(p.canvas_mask(part - p.canvas_box.tl()), true);
            gt.area_px = static_cast<int>(m.m00);
            if (m.m00 > 0) {
                gt.mass_x_px = part.x + m.m10 / m.m00;
                gt.mass_y_px = part.y - view.y + m.m01 / m.m00;
            }
        }
        frame.stems.push_back(std::move(gt));
        frame.plant_ids.push_back(p.id);
    }
    return frame;
}

}  // namespace stemd::synth
