#include "stemd/runtime/class_provider.hpp"

#include <algorithm>
#include <cmath>

#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

ModelClassProvider::ModelClassProvider(vision::PlantClassifier model, cv::Size frame_size,
                                       const vision::Params& params, const ClassifyConfig& config)
    : model_(std::move(model)), workspace_(frame_size, params),
      cells_(frame_size, params.gsd_mm_per_px, model_.info().cell_mm), config_(config)
{
}

void ModelClassProvider::classify(const drivers::Frame& frame, const vision::Params& params,
                                  const vision::Workspace& workspace, FrameResult& result)
{
    // The model's class, even where a recording has a class column too:
    // what runs in the field is what a replay shows. A frame without its
    // rgb image leaves every plant unknown.
    const vision::FrameView view{.bgr = frame.bgr, .nir = frame.nir, .mask = frame.mask};
    // Each plant's class from the share of its cells (vision/cells): on the
    // shared sets as safe for the crop as the class map around the stem,
    // and it treats more weeds (README, Crop or weed).
    vision::plant_features(view, params, workspace, result.detections, workspace_);
    vision::cell_features(view, params, workspace, result.detections, workspace_, cells_);
    vision::classify_cells(model_, cells_);
    const std::size_t plants = result.detections.plants.size();
    std::fill(result.plant_class.begin(), result.plant_class.begin() + static_cast<std::ptrdiff_t>(plants),
              PlantClass::Unknown);
    if (workspace_.features().size() == plants) {
        vision::classify_plants(model_, workspace_, cells_, plants, config_.min_confidence, config_.weed_confidence,
                                probabilities_, result.plant_class);
        // Weeds grown into a crop get targets of their own.
        if (config_.weed_parts) {
            const vision::WeedTargetCounts added = vision::add_weed_parts(
                cells_, weed_target_params(config_), result.detections, result.plant_class, probabilities_);
            bump(counters_.weed_parts, added.parts);
            bump(counters_.stemless_weeds, added.stemless);
            bump(counters_.weed_cover, added.cover);
        }
    }
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
