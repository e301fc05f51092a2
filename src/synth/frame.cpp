// Synthetic field frames. Outline of one frame:
//   1. soil (soil.cpp): multi-scale value noise, clods and stones (colour + NIR);
//   2. layout (layout.cpp): plants drawn as parameters (plant.cpp), placed
//      without overlap (but for the canopy preset);
//   3. plants (plant_render.cpp): each leaf (and crown, grass blade) is one
//      anti-aliased layer composited over the image, with its hard fill
//      going into the mask; fragmentation cuts gaps and holes out of both;
//   4. sensor (sensor.cpp): a light blur on colour and NIR (not the mask),
//      then noise.
// Every random number comes from our own splitmix64 streams keyed on
// (seed, preset, frame, purpose) (random.cpp), and is turned into numbers
// by integer or IEEE-exact arithmetic, so frames are byte-identical across
// runs. Separate streams keep e.g. the layout unchanged when only the
// fragmentation changes.
#include "frame.hpp"

#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "layout.hpp"
#include "sensor.hpp"
#include "soil.hpp"

namespace stemd::synth {

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

void render_ground(Canvas& canvas, const PresetSpec& spec, double px_per_mm, Rng& soil)
{
    const cv::Size size = canvas.bgr.size();
    render_soil_texture(canvas.bgr, canvas.nir, px_per_mm, spec.soil_brightness, soil);
    render_clods_and_stones(canvas.bgr, canvas.nir, px_per_mm, spec.clods_per_m2, spec.stones_per_m2, soil);
    canvas.leaf_texture.assign(static_cast<std::size_t>(size.area()), 0.0f);
    add_value_noise(canvas.leaf_texture, size, 3 * px_per_mm, 0.6f, soil);
    add_value_noise(canvas.leaf_texture, size, 1 * px_per_mm, 0.4f, soil);
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
    render_ground(canvas, spec, px_per_mm, soil);

    Rng layout = make_stream(options, frame_index, Stream::layout);
    Rng fragments = make_stream(options, frame_index, Stream::fragments);
    Frame frame;
    for (const Plant& plant : make_layout(spec, size, px_per_mm, layout)) {
        const GroundTruthStem gt = render_plant(canvas, plant, fragmentation, px_per_mm, fragments);
        const bool inside = gt.x_px >= 0 && gt.y_px >= 0 && gt.x_px <= size.width - 1 && gt.y_px <= size.height - 1;
        if (plant.shape != PlantShape::grass_tuft && inside)
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

}  // namespace stemd::synth
