// The vision pipeline's parameters from the configuration.
#pragma once

#include "stemd/runtime/config.hpp"
#include "stemd/vision/types.hpp"

namespace stemd::config {

// camera.gsd_mm_per_px, segment.*, closing.radius_px, plants.min_area_mm2,
// leaves.defect_depth_mm and stem.* into vision::Params. The schema has
// already checked every value, so this cannot fail.
vision::Params vision_params(const Config& config);

}  // namespace stemd::config
