#include "stemd/runtime/vision_config.hpp"

namespace stemd::config {

vision::Params vision_params(const Config& config)
{
    vision::Params p;
    // The schema only admits choices these parsers know; keep the library
    // default should one ever be missing.
    if (const auto v = vision::parse_segmentation(config.get_text("segment.method")))
        p.segmentation = *v;
    if (const auto v = vision::parse_threshold_method(config.get_text("segment.threshold")))
        p.threshold = *v;
    if (const auto v = vision::parse_mask_vegetation(config.get_text("segment.mask_vegetation")))
        p.mask_vegetation = *v;
    if (const auto v = vision::parse_stem_estimator(config.get_text("stem.method")))
        p.stem_estimator = *v;
    p.min_class_separation = config.get_real("segment.min_class_separation");
    p.soil_sigmas = config.get_real("segment.soil_sigmas");
    p.smooth_index = config.get_bool("segment.smooth");
    p.opening_radius_px = static_cast<int>(config.get_int("segment.opening_radius_px"));
    p.closing_radius_px = static_cast<int>(config.get_int("closing.radius_px"));
    p.gsd_mm_per_px = config.get_real("camera.gsd_mm_per_px");
    p.min_plant_area_mm2 = config.get_real("plants.min_area_mm2");
    p.group_gap_mm = config.get_real("plants.group_gap_mm");
    p.defect_depth_mm = config.get_real("leaves.defect_depth_mm");
    p.min_leaves = static_cast<int>(config.get_int("stem.min_leaves"));
    p.min_intersection_angle_deg = config.get_real("stem.min_angle_deg");
    p.defect_depth_rel = config.get_real("leaves.defect_depth_rel");
    p.min_confidence = config.get_real("stem.min_confidence");
    p.grass_min_area_mm2 = config.get_real("stem.grass_min_area_mm2");
    p.grass_max_width_mm = config.get_real("stem.grass_max_width_mm");
    p.grass_max_hull_fill = config.get_real("stem.grass_max_hull_fill");
    return p;
}

}  // namespace stemd::config
