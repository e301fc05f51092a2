// Moving field strips (see synth.hpp): one canvas for the whole strip,
// frames are crops of it at the odometer's row.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "frame.hpp"
#include "layout.hpp"
#include "sensor.hpp"
#include "stemd/synth/synth.hpp"

namespace stemd::synth {

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
            p.plant = i < crops           ? make_rosette(PlantClass::Crop, spec.crop, px_per_mm, rng)
                      : i < crops + weeds ? make_rosette(PlantClass::Weed, spec.weed, px_per_mm, rng)
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
    render_ground(canvas, spec, px_per_mm, soil);

    Rng fragments = make_strip_stream(options, 0, Stream::fragments);
    const double cx = (options.width_px - 1) / 2.0;
    std::vector<StripPlant> stemmed;
    for (const StripLayoutPlant& p : layout) {
        Plant plant = p.plant;
        plant.stem_px = {cx - p.y_mm * px_per_mm, (strip.top_s_mm - p.s_mm) * px_per_mm};
        StripPlant sp;
        const GroundTruthStem gt =
            render_plant(canvas, plant, fragmentation, px_per_mm, fragments, &sp.canvas_mask, &sp.canvas_box);
        if (plant.shape == PlantShape::grass_tuft) {
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
