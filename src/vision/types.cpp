#include "stemd/vision/types.hpp"

#include "stemd/base/enum_names.hpp"

namespace stemd::vision {

namespace {

using base::EnumName;
using base::name_of;
using base::value_of;

constexpr EnumName<Segmentation> kSegmentations[]{
    {Segmentation::exg, "exg"}, {Segmentation::chromatic_exg, "chromatic_exg"}, {Segmentation::ndvi, "ndvi"},
    {Segmentation::mask, "mask"}, {Segmentation::exg_and_ndvi, "exg_and_ndvi"}};
constexpr EnumName<ThresholdMethod> kThresholdMethods[]{{ThresholdMethod::otsu, "otsu"},
                                                        {ThresholdMethod::triangle, "triangle"},
                                                        {ThresholdMethod::min_error, "min_error"},
                                                        {ThresholdMethod::above_soil, "above_soil"}};
constexpr EnumName<MaskVegetation> kMaskVegetations[]{{MaskVegetation::nonzero, "nonzero"},
                                                      {MaskVegetation::zero, "zero"}};
constexpr EnumName<StemMethod> kStemMethods[]{{StemMethod::leaves, "leaves"}, {StemMethod::com, "com"}};
constexpr EnumName<StemEstimator> kStemEstimators[]{
    {StemEstimator::robust, "robust"}, {StemEstimator::paper, "paper"}, {StemEstimator::com, "com"}};
constexpr EnumName<ComReason> kComReasons[]{
    {ComReason::none, "none"}, {ComReason::method_com, "method_com"}, {ComReason::too_few_leaves, "too_few_leaves"},
    {ComReason::no_intersections, "no_intersections"}, {ComReason::outside_box, "outside_box"},
    {ComReason::contour_overflow, "contour_overflow"}, {ComReason::ill_conditioned, "ill_conditioned"}};
constexpr EnumName<DetectStatus> kDetectStatuses[]{
    {DetectStatus::ok, "ok"}, {DetectStatus::empty_frame, "empty_frame"}, {DetectStatus::bad_format, "bad_format"},
    {DetectStatus::size_mismatch, "size_mismatch"}, {DetectStatus::missing_nir, "missing_nir"},
    {DetectStatus::missing_mask, "missing_mask"}};

}  // namespace

std::string_view to_string(Segmentation v) { return name_of(kSegmentations, v); }
std::string_view to_string(ThresholdMethod v) { return name_of(kThresholdMethods, v); }
std::string_view to_string(MaskVegetation v) { return name_of(kMaskVegetations, v); }
std::string_view to_string(StemMethod v) { return name_of(kStemMethods, v); }
std::string_view to_string(StemEstimator v) { return name_of(kStemEstimators, v); }
std::string_view to_string(ComReason v) { return name_of(kComReasons, v); }
std::string_view to_string(DetectStatus v) { return name_of(kDetectStatuses, v); }

std::optional<Segmentation> parse_segmentation(std::string_view s) { return value_of(kSegmentations, s); }
std::optional<ThresholdMethod> parse_threshold_method(std::string_view s) { return value_of(kThresholdMethods, s); }
std::optional<MaskVegetation> parse_mask_vegetation(std::string_view s) { return value_of(kMaskVegetations, s); }
std::optional<StemEstimator> parse_stem_estimator(std::string_view s) { return value_of(kStemEstimators, s); }

}  // namespace stemd::vision
