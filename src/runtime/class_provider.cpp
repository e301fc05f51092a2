#include "stemd/runtime/class_provider.hpp"

#include <algorithm>
#include <cmath>

#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

std::uint64_t plant_classes_from_map(const cv::Mat& class_map, cv::Size frame_size,
                                     const vision::Detections& detections,
                                     std::array<PlantClass, vision::kMaxPlants>& out) noexcept
{
    std::uint64_t bad = 0;
    constexpr double kHalf = 4;   // the window's half-width in frame pixels
    const double sx = static_cast<double>(class_map.cols) / std::max(frame_size.width, 1);
    const double sy = static_cast<double>(class_map.rows) / std::max(frame_size.height, 1);
    for (std::size_t i = 0; i < detections.plants.size(); ++i) {
        const vision::Plant& p = detections.plants[i];
        out[i] = PlantClass::Unknown;
        if (!p.has_stem || class_map.empty())
            continue;
        // The window's pixels in the map: the frame pixels' cells, however
        // coarse the map (one cell at least).
        const int x0 = std::max(static_cast<int>(std::floor((p.stem.x - kHalf) * sx)), 0);
        const int x1 = std::min(static_cast<int>(std::floor((p.stem.x + kHalf) * sx)), class_map.cols - 1);
        const int y0 = std::max(static_cast<int>(std::floor((p.stem.y - kHalf) * sy)), 0);
        const int y1 = std::min(static_cast<int>(std::floor((p.stem.y + kHalf) * sy)), class_map.rows - 1);
        int crop = 0, weed = 0, other = 0;
        for (int y = y0; y <= y1; ++y) {
            const std::uint8_t* row = class_map.ptr<std::uint8_t>(y);
            for (int x = x0; x <= x1; ++x) {
                crop += plant_class_from_value(row[x]) == PlantClass::Crop;
                weed += plant_class_from_value(row[x]) == PlantClass::Weed;
                other += row[x] > 2;
            }
        }
        out[i] = weed > crop ? PlantClass::Weed : crop > weed ? PlantClass::Crop : PlantClass::Unknown;
        bad += other > 0;
    }
    return bad;
}

ModelClassProvider::ModelClassProvider(vision::PlantClassifier model, cv::Size frame_size,
                                       const vision::Params& params, double min_confidence, double weed_confidence)
    : model_(std::move(model)), workspace_(frame_size, params), min_confidence_(min_confidence),
      weed_confidence_(weed_confidence)
{
}

void ModelClassProvider::classify(const drivers::Frame& frame, const vision::Params& params,
                                  const vision::Workspace& workspace, FrameResult& result)
{
    // The model's class, even where a recording has a class column too:
    // what runs in the field is what a replay shows. A frame without its
    // rgb image leaves every plant unknown.
    const vision::FrameView view{.bgr = frame.bgr, .nir = frame.nir, .mask = frame.mask};
    vision::plant_features(view, params, workspace, result.detections, workspace_);
    const auto features = workspace_.features();
    for (std::size_t i = 0; i < result.detections.plants.size(); ++i)
        result.plant_class[i] =
            i < features.size()
                ? vision::decide_class(model_.weed_probability(features[i]), min_confidence_, weed_confidence_)
                : PlantClass::Unknown;
    result.has_class_map = true;
}

void RecordingClassProvider::classify(const drivers::Frame& frame, const vision::Params& /*params*/,
                                      const vision::Workspace& /*workspace*/, FrameResult& result)
{
    result.has_class_map = frame.has_class_map && !frame.plant_class.empty();
    if (result.has_class_map)
        bump(counters_.bad_class, plant_classes_from_map(frame.plant_class, frame.plant_class.size(),
                                                         result.detections, result.plant_class));
}

}  // namespace stemd::runtime
