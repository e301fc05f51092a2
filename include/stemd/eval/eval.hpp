// Evaluation against ground truth: stem positions (the paper's criterion: a
// detected stem is correct when it lies within 0.5 cm of a true stem) and
// vegetation masks (intersection over union), and crop/weed class maps per
// pixel of the annotated vegetation.
#pragma once

#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace stemd::eval {

// One stem position in one image; x, y in pixels, pixel centres at integers.
struct StemPoint {
    std::string image;  // as written in the CSV (a frames.csv path or a file name)
    double x_px = 0;
    double y_px = 0;
};

// Reads the columns image, x and y (found by header name, other columns are
// ignored) of a ground-truth stems.csv (image,x,y,kind,leaves) or of a
// `stemd-detect --csv` file (image,plant,x,y,method,leaves,area_px).
// Numbers may carry surrounding blanks; the image name is taken as written and
// must not be empty. On failure returns nullopt and sets `error`:
//   "<path>: cannot open", "<path>: header has no column 'x' (columns: ...)",
//   "<path>:<line>: x 'abc' is not a finite number", ...
std::optional<std::vector<StemPoint>> read_stem_points(const std::filesystem::path& csv, std::string& error);

// A CSV cell as a finite number (surrounding blanks ignored); false if it is
// empty, not a number, has trailing text, or is infinite/NaN.
bool parse_finite(std::string_view text, double& out);

struct MatchResult {
    int ground_truth = 0;    // number of ground-truth stems
    int predictions = 0;     // number of detected stems
    int true_positives = 0;  // matched pairs
    // Fractions in [0, 1]. Zero denominators give 0, never NaN:
    //   precision = TP / predictions       (0 when there are no predictions)
    //   recall    = TP / ground_truth      (0 when there is no ground truth)
    //   f1        = 2 TP / (ground_truth + predictions)   (the harmonic mean
    //               of precision and recall; 0 when both counts are 0)
    double precision = 0;
    double recall = 0;
    double f1 = 0;
    double mean_error_mm = 0;  // mean distance of the matched pairs; 0 without any
};

// Matches detections to ground truth one-to-one, separately per image (equal
// `image` strings; an image in only one of the lists has all its points
// unmatched). Candidates are all (gt, pred) pairs at most tol_mm apart, the
// distance in pixels times gsd_mm_per_px ("at most" with a relative slack of
// 1e-9 so that a pair exactly at the tolerance is not lost to rounding).
// Greedy, closest pair first, ties broken by ground-truth index and then by
// prediction index (indices into the given spans), each point used at most
// once - so the result does not depend on anything but the input order.
// tol_mm and gsd_mm_per_px must be finite and > 0; otherwise nothing matches.
MatchResult match_stems(std::span<const StemPoint> ground_truth, std::span<const StemPoint> predictions,
                        double tol_mm, double gsd_mm_per_px);

struct IouResult {
    long intersection_px = 0;
    long union_px = 0;
    double iou = 0;  // intersection / union; 1 when both masks have no vegetation
};

// Intersection over union of the vegetation in two masks: CV_8UC1, any
// nonzero value is vegetation. Both must be non-empty and of the same size;
// otherwise returns nullopt and says why in `error` (with both sizes/types).
std::optional<IouResult> mask_iou(const cv::Mat& predicted, const cv::Mat& ground_truth, std::string& error);

// How a class map (0 soil or unclassified, 1 crop, 2 weed: `stemd-detect
// --class-out`) calls the annotated vegetation of a class image (1 crop,
// 2 weed; every other value is not scored). An annotated pixel the map
// calls soil (not segmented, or a cell left unclassified) is right for
// neither class, as stemd-train counts it.
struct ClassScore {
    long crop_px = 0, weed_px = 0;             // annotated
    long crop_right = 0, weed_right = 0;       // called their own class
    long crop_as_weed = 0, weed_as_crop = 0;   // called the other class
    // The rest of each class was called soil.
    long crop_as_soil() const { return crop_px - crop_right - crop_as_weed; }
    long weed_as_soil() const { return weed_px - weed_right - weed_as_crop; }

    ClassScore& operator+=(const ClassScore& o);
    // right / annotated of that class; 1 when it has no pixel.
    double crop_recall() const;
    double weed_recall() const;
    // The mean of the recalls of the classes the annotation holds: both,
    // else the one, else 1 (nothing to get wrong).
    double balanced_accuracy() const;
};

// Both CV_8UC1 of one size; a predicted value above 2 is no class (error).
std::optional<ClassScore> class_map_score(const cv::Mat& predicted, const cv::Mat& truth, std::string& error);

}  // namespace stemd::eval
