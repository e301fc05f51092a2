#include "stemd/runtime/class_provider.hpp"

#include <algorithm>
#include <cmath>

#include "stemd/runtime/status.hpp"

namespace stemd::runtime {

ModelClassProvider::ModelClassProvider(vision::PlantClassifier model, cv::Size frame_size,
                                       const vision::Params& params, const vision::ModelClassParams& class_params)
    : model_(std::move(model)), workspace_(frame_size, params),
      cells_(frame_size, params.gsd_mm_per_px, model_.info().cell_mm), params_(class_params)
{
}

void ModelClassProvider::classify(const drivers::Frame& frame, const vision::Params& params,
                                  const vision::Workspace& workspace, FrameResult& result)
{
    // The model's class, even where a recording has a class column too:
    // what runs in the field is what a replay shows. A frame without its
    // rgb image leaves every plant unknown. Each plant's class comes from
    // the share of its cells (vision/cells): on the shared sets as safe for
    // the crop as the class map around the stem, and it treats more weeds
    // (README, Crop or weed); weeds grown into a crop get targets of their
    // own.
    const vision::FrameView view{.bgr = frame.bgr, .nir = frame.nir, .mask = frame.mask};
    const vision::ModelClassCounts counts =
        vision::classify_frame(model_, params_, view, params, workspace, result.detections, workspace_, cells_,
                               probabilities_, result.plant_class);
    bump(counters_.weed_parts, counts.weed_targets.parts);
    bump(counters_.stemless_weeds, counts.weed_targets.stemless);
    bump(counters_.weed_cover, counts.weed_targets.cover);
    if (counts.cells_over_budget > 0) {
        bump(counters_.cells_over_budget, counts.cells_over_budget);
        bump(counters_.frames_over_budget, 1);
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
