#include "stemd/vision/types.hpp"

namespace stemd::vision {

std::string_view to_string(Segmentation v)
{
    switch (v) {
    case Segmentation::exg: return "exg";
    case Segmentation::chromatic_exg: return "chromatic_exg";
    case Segmentation::ndvi: return "ndvi";
    case Segmentation::mask: return "mask";
    case Segmentation::exg_and_ndvi: return "exg_and_ndvi";
    }
    return "?";
}

std::string_view to_string(ThresholdMethod v)
{
    switch (v) {
    case ThresholdMethod::otsu: return "otsu";
    case ThresholdMethod::triangle: return "triangle";
    case ThresholdMethod::min_error: return "min_error";
    case ThresholdMethod::above_soil: return "above_soil";
    }
    return "?";
}

std::string_view to_string(MaskVegetation v)
{
    switch (v) {
    case MaskVegetation::nonzero: return "nonzero";
    case MaskVegetation::zero: return "zero";
    }
    return "?";
}

std::string_view to_string(StemMethod v)
{
    switch (v) {
    case StemMethod::leaves: return "leaves";
    case StemMethod::com: return "com";
    }
    return "?";
}

std::string_view to_string(StemEstimator v)
{
    switch (v) {
    case StemEstimator::robust: return "robust";
    case StemEstimator::paper: return "paper";
    case StemEstimator::com: return "com";
    }
    return "?";
}

std::string_view to_string(ComReason v)
{
    switch (v) {
    case ComReason::none: return "none";
    case ComReason::method_com: return "method_com";
    case ComReason::too_few_leaves: return "too_few_leaves";
    case ComReason::no_intersections: return "no_intersections";
    case ComReason::outside_box: return "outside_box";
    case ComReason::contour_overflow: return "contour_overflow";
    case ComReason::ill_conditioned: return "ill_conditioned";
    }
    return "?";
}

std::string_view to_string(DetectStatus v)
{
    switch (v) {
    case DetectStatus::ok: return "ok";
    case DetectStatus::empty_frame: return "empty_frame";
    case DetectStatus::bad_format: return "bad_format";
    case DetectStatus::size_mismatch: return "size_mismatch";
    case DetectStatus::missing_nir: return "missing_nir";
    case DetectStatus::missing_mask: return "missing_mask";
    }
    return "?";
}

std::optional<Segmentation> parse_segmentation(std::string_view s)
{
    if (s == "exg") return Segmentation::exg;
    if (s == "chromatic_exg") return Segmentation::chromatic_exg;
    if (s == "ndvi") return Segmentation::ndvi;
    if (s == "mask") return Segmentation::mask;
    if (s == "exg_and_ndvi") return Segmentation::exg_and_ndvi;
    return std::nullopt;
}

std::optional<ThresholdMethod> parse_threshold_method(std::string_view s)
{
    if (s == "otsu") return ThresholdMethod::otsu;
    if (s == "triangle") return ThresholdMethod::triangle;
    if (s == "min_error") return ThresholdMethod::min_error;
    if (s == "above_soil") return ThresholdMethod::above_soil;
    return std::nullopt;
}

std::optional<MaskVegetation> parse_mask_vegetation(std::string_view s)
{
    if (s == "nonzero") return MaskVegetation::nonzero;
    if (s == "zero") return MaskVegetation::zero;
    return std::nullopt;
}

std::optional<StemEstimator> parse_stem_estimator(std::string_view s)
{
    if (s == "robust") return StemEstimator::robust;
    if (s == "paper") return StemEstimator::paper;
    if (s == "com") return StemEstimator::com;
    return std::nullopt;
}

}  // namespace stemd::vision
