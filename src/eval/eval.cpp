#include "stemd/eval/eval.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string_view>
#include <system_error>
#include <tuple>

#include <opencv2/core.hpp>

#include "stemd/base/strings.hpp"
#include "stemd/io/csv.hpp"

namespace stemd::eval {

namespace {

std::string join(const std::vector<std::string>& fields)
{
    std::string out;
    for (std::size_t i = 0; i < fields.size(); ++i)
        out += (i ? "," : "") + fields[i];
    return out;
}

double ratio(int numerator, int denominator)
{
    return denominator > 0 ? static_cast<double>(numerator) / denominator : 0.0;
}

struct Candidate {
    double distance_sq_px;
    std::size_t gt;
    std::size_t pred;
};

}  // namespace

std::optional<std::vector<StemPoint>> read_stem_points(const std::filesystem::path& csv, std::string& error)
{
    const auto table = io::read_csv(csv, error);
    if (!table)
        return std::nullopt;
    int columns[3];
    const char* const names[3] = {"image", "x", "y"};
    for (int c = 0; c < 3; ++c) {
        columns[c] = table->column(names[c]);
        if (columns[c] < 0) {
            error = csv.string() + ": header has no column '" + names[c] + "' (columns: " + join(table->header) + ")";
            return std::nullopt;
        }
    }
    std::vector<StemPoint> points;
    points.reserve(table->rows.size());
    for (const auto& row : table->rows) {
        const std::string where = csv.string() + ":" + std::to_string(row.line) + ": ";
        StemPoint p;
        p.image = row.fields[static_cast<std::size_t>(columns[0])];
        if (p.image.empty()) {
            error = where + "image is empty";
            return std::nullopt;
        }
        double* const values[2] = {&p.x_px, &p.y_px};
        for (int c = 1; c < 3; ++c) {
            const std::string& text = row.fields[static_cast<std::size_t>(columns[c])];
            if (!parse_finite(text, *values[c - 1])) {
                error = where + names[c] + " '" + text + "' is not a finite number";
                return std::nullopt;
            }
        }
        points.push_back(std::move(p));
    }
    return points;
}

MatchResult match_stems(std::span<const StemPoint> ground_truth, std::span<const StemPoint> predictions,
                        double tol_mm, double gsd_mm_per_px)
{
    MatchResult r;
    r.ground_truth = static_cast<int>(ground_truth.size());
    r.predictions = static_cast<int>(predictions.size());

    const bool valid = std::isfinite(tol_mm) && tol_mm > 0 && std::isfinite(gsd_mm_per_px) && gsd_mm_per_px > 0;
    if (valid) {
        // Indices per image; std::map keeps the iteration order independent of hashing.
        std::map<std::string_view, std::pair<std::vector<std::size_t>, std::vector<std::size_t>>> images;
        for (std::size_t i = 0; i < ground_truth.size(); ++i)
            images[ground_truth[i].image].first.push_back(i);
        for (std::size_t j = 0; j < predictions.size(); ++j)
            images[predictions[j].image].second.push_back(j);

        const double tol_px = tol_mm / gsd_mm_per_px;
        const double limit_sq_px = tol_px * tol_px * (1 + 2e-9);  // (1 + 1e-9)^2, see the header
        double error_sum_mm = 0;
        std::vector<Candidate> candidates;
        std::vector<bool> gt_used, pred_used;
        for (const auto& [image, lists] : images) {
            const auto& [gts, preds] = lists;
            if (gts.empty() || preds.empty())
                continue;
            candidates.clear();
            for (const std::size_t i : gts) {
                for (const std::size_t j : preds) {
                    const double dx = predictions[j].x_px - ground_truth[i].x_px;
                    const double dy = predictions[j].y_px - ground_truth[i].y_px;
                    const double d2 = dx * dx + dy * dy;
                    if (d2 <= limit_sq_px)
                        candidates.push_back({d2, i, j});
                }
            }
            std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
                return std::tie(a.distance_sq_px, a.gt, a.pred) < std::tie(b.distance_sq_px, b.gt, b.pred);
            });
            gt_used.assign(ground_truth.size(), false);
            pred_used.assign(predictions.size(), false);
            for (const Candidate& c : candidates) {
                if (gt_used[c.gt] || pred_used[c.pred])
                    continue;
                gt_used[c.gt] = pred_used[c.pred] = true;
                ++r.true_positives;
                error_sum_mm += std::sqrt(c.distance_sq_px) * gsd_mm_per_px;
            }
        }
        if (r.true_positives > 0)
            r.mean_error_mm = error_sum_mm / r.true_positives;
    }
    r.precision = ratio(r.true_positives, r.predictions);
    r.recall = ratio(r.true_positives, r.ground_truth);
    r.f1 = ratio(2 * r.true_positives, r.ground_truth + r.predictions);
    return r;
}

namespace {

// Whether a prediction and its ground truth (`what`: "mask", "class map")
// are both non-empty 8-bit single-channel images of one size; else false
// with `error` saying which and both sizes and types.
bool same_grey_images(const cv::Mat& predicted, const cv::Mat& ground_truth, const std::string& what,
                      std::string& error)
{
    const auto describe = [](const cv::Mat& m) {
        return std::to_string(m.cols) + "x" + std::to_string(m.rows) + " " + cv::typeToString(m.type());
    };
    if (predicted.empty() || ground_truth.empty()) {
        error = std::string(predicted.empty() ? "predicted " : "ground-truth ") + what + " is empty";
        return false;
    }
    if (predicted.type() != CV_8UC1 || ground_truth.type() != CV_8UC1) {
        error = what + "s must be 8-bit single-channel (CV_8UC1): predicted " + describe(predicted) +
                ", ground truth " + describe(ground_truth);
        return false;
    }
    if (predicted.size() != ground_truth.size()) {
        error = what + " sizes differ: predicted " + describe(predicted) + ", ground truth " + describe(ground_truth);
        return false;
    }
    return true;
}

}  // namespace

std::optional<IouResult> mask_iou(const cv::Mat& predicted, const cv::Mat& ground_truth, std::string& error)
{
    if (!same_grey_images(predicted, ground_truth, "mask", error))
        return std::nullopt;
    IouResult r;
    for (int y = 0; y < predicted.rows; ++y) {
        const auto* p = predicted.ptr<std::uint8_t>(y);
        const auto* g = ground_truth.ptr<std::uint8_t>(y);
        long both = 0, any = 0;
        for (int x = 0; x < predicted.cols; ++x) {
            const bool a = p[x] != 0, b = g[x] != 0;
            both += a && b;
            any += a || b;
        }
        r.intersection_px += both;
        r.union_px += any;
    }
    r.iou = r.union_px > 0 ? static_cast<double>(r.intersection_px) / static_cast<double>(r.union_px) : 1.0;
    return r;
}

ClassScore& ClassScore::operator+=(const ClassScore& o)
{
    crop_px += o.crop_px;
    weed_px += o.weed_px;
    crop_right += o.crop_right;
    weed_right += o.weed_right;
    crop_as_weed += o.crop_as_weed;
    weed_as_crop += o.weed_as_crop;
    return *this;
}

double ClassScore::crop_recall() const
{
    return crop_px > 0 ? static_cast<double>(crop_right) / static_cast<double>(crop_px) : 1.0;
}

double ClassScore::weed_recall() const
{
    return weed_px > 0 ? static_cast<double>(weed_right) / static_cast<double>(weed_px) : 1.0;
}

double ClassScore::balanced_accuracy() const
{
    if (crop_px > 0 && weed_px > 0)
        return 0.5 * (crop_recall() + weed_recall());
    if (crop_px > 0)
        return crop_recall();
    return weed_recall();
}

std::optional<ClassScore> class_map_score(const cv::Mat& predicted, const cv::Mat& truth, std::string& error)
{
    if (!same_grey_images(predicted, truth, "class map", error))
        return std::nullopt;
    ClassScore s;
    for (int y = 0; y < predicted.rows; ++y) {
        const auto* p = predicted.ptr<std::uint8_t>(y);
        const auto* t = truth.ptr<std::uint8_t>(y);
        for (int x = 0; x < predicted.cols; ++x) {
            if (p[x] > 2) {
                error = "predicted class map holds " + std::to_string(p[x]) + " at (" + std::to_string(x) + ", " +
                        std::to_string(y) + "): not 0 soil, 1 crop or 2 weed";
                return std::nullopt;
            }
            if (t[x] == 1) {
                ++s.crop_px;
                s.crop_right += p[x] == 1;
                s.crop_as_weed += p[x] == 2;
            } else if (t[x] == 2) {
                ++s.weed_px;
                s.weed_right += p[x] == 2;
                s.weed_as_crop += p[x] == 1;
            }
        }
    }
    return s;
}

bool parse_finite(std::string_view text, double& out)
{
    text = base::trim(text);
    if (text.empty())
        return false;
    const char* const end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, out);
    return ec == std::errc() && ptr == end && std::isfinite(out);
}

}  // namespace stemd::eval
