#include "stemd/vision/types.hpp"

#include "stemd/base/enum_names.hpp"

namespace stemd::vision {

namespace {

using base::EnumName;
using base::name_of;
using base::value_of;

constexpr EnumName<StemMethod> kStemMethods[]{{StemMethod::leaves, "leaves"}, {StemMethod::com, "com"}};
constexpr EnumName<ComReason> kComReasons[]{
    {ComReason::none, "none"}, {ComReason::method_com, "method_com"}, {ComReason::too_few_leaves, "too_few_leaves"},
    {ComReason::no_intersections, "no_intersections"}, {ComReason::outside_box, "outside_box"},
    {ComReason::contour_overflow, "contour_overflow"}, {ComReason::ill_conditioned, "ill_conditioned"},
    {ComReason::weed_part, "weed_part"}, {ComReason::stemless_weed, "stemless_weed"},
    {ComReason::weed_cover, "weed_cover"}};
constexpr EnumName<DetectStatus> kDetectStatuses[]{
    {DetectStatus::ok, "ok"}, {DetectStatus::empty_frame, "empty_frame"}, {DetectStatus::bad_format, "bad_format"},
    {DetectStatus::size_mismatch, "size_mismatch"}, {DetectStatus::missing_nir, "missing_nir"},
    {DetectStatus::missing_mask, "missing_mask"}};

}  // namespace

std::string_view to_string(Segmentation v) { return name_of(kSegmentationNames, v); }
std::string_view to_string(ThresholdMethod v) { return name_of(kThresholdMethodNames, v); }
std::string_view to_string(MaskVegetation v) { return name_of(kMaskVegetationNames, v); }
std::string_view to_string(StemMethod v) { return name_of(kStemMethods, v); }
std::string_view to_string(StemEstimator v) { return name_of(kStemEstimatorNames, v); }
std::string_view to_string(ComReason v) { return name_of(kComReasons, v); }
std::string_view to_string(DetectStatus v) { return name_of(kDetectStatuses, v); }

std::optional<Segmentation> parse_segmentation(std::string_view s) { return value_of(kSegmentationNames, s); }
std::optional<ThresholdMethod> parse_threshold_method(std::string_view s) { return value_of(kThresholdMethodNames, s); }
std::optional<MaskVegetation> parse_mask_vegetation(std::string_view s) { return value_of(kMaskVegetationNames, s); }
std::optional<StemEstimator> parse_stem_estimator(std::string_view s) { return value_of(kStemEstimatorNames, s); }

}  // namespace stemd::vision
