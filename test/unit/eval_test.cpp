#include "stemd/eval/eval.hpp"
#include "temp_dir_test.hpp"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace fs = std::filesystem;
using stemd::eval::mask_iou;
using stemd::eval::match_stems;
using stemd::eval::MatchResult;
using stemd::eval::read_stem_points;
using stemd::eval::StemPoint;

namespace {

// gsd 1 mm/px and tol 5 mm: the tolerance is 5 px, distances in px are mm.
constexpr double kTol = 5.0;
constexpr double kGsd = 1.0;

MatchResult match(const std::vector<StemPoint>& gt, const std::vector<StemPoint>& pred, double tol = kTol,
                  double gsd = kGsd)
{
    return match_stems(gt, pred, tol, gsd);
}

// --- match_stems -------------------------------------------------------------

TEST(EvalMatch, PerfectMatch)
{
    const std::vector<StemPoint> gt{{"a", 10, 10}, {"a", 50, 50}};
    const auto r = match(gt, gt);
    EXPECT_EQ(r.ground_truth, 2);
    EXPECT_EQ(r.predictions, 2);
    EXPECT_EQ(r.true_positives, 2);
    EXPECT_EQ(r.precision, 1.0);
    EXPECT_EQ(r.recall, 1.0);
    EXPECT_EQ(r.f1, 1.0);
    EXPECT_EQ(r.mean_error_mm, 0.0);
}

TEST(EvalMatch, ExactlyAtToleranceIsInsideJustBeyondIsOutside)
{
    // gsd 0.5 mm/px, tol 5 mm = 10 px.
    const std::vector<StemPoint> gt{{"a", 0, 0}};
    EXPECT_EQ(match(gt, {{"a", 10, 0}}, 5.0, 0.5).true_positives, 1);
    EXPECT_EQ(match(gt, {{"a", 6, 8}}, 5.0, 0.5).true_positives, 1);  // 3-4-5: 10 px
    EXPECT_EQ(match(gt, {{"a", 9.99, 0}}, 5.0, 0.5).true_positives, 1);
    EXPECT_EQ(match(gt, {{"a", 10.01, 0}}, 5.0, 0.5).true_positives, 0);
    EXPECT_EQ(match(gt, {{"a", 6, 8.02}}, 5.0, 0.5).true_positives, 0);
}

TEST(EvalMatch, BoundaryNotLostToRounding)
{
    // 0.3 / 0.1 = 2.9999999999999996 in doubles; 3 px at 0.1 mm/px is 0.3 mm, inside.
    const std::vector<StemPoint> gt{{"a", 0, 0}};
    EXPECT_EQ(match(gt, {{"a", 3, 0}}, 0.3, 0.1).true_positives, 1);
    EXPECT_EQ(match(gt, {{"a", 3.001, 0}}, 0.3, 0.1).true_positives, 0);
}

TEST(EvalMatch, MeanErrorIsInMillimetres)
{
    // 5 px and 10 px at 0.25 mm/px: 1.25 mm and 2.5 mm.
    const std::vector<StemPoint> gt{{"a", 0, 0}, {"a", 100, 100}};
    const std::vector<StemPoint> pred{{"a", 3, 4}, {"a", 106, 108}};
    const auto r = match(gt, pred, 5.0, 0.25);
    EXPECT_EQ(r.true_positives, 2);
    EXPECT_DOUBLE_EQ(r.mean_error_mm, (1.25 + 2.5) / 2);
}

TEST(EvalMatch, ClosestPairsFirstNotInputOrder)
{
    // p0 lies 3 px from g0 and 1 px from g1; p1 only reaches g0 (4.5 px).
    // Taking the ground truth in order and giving each its nearest free
    // prediction pairs g0-p0 and leaves g1 without (p1 is 8.5 px away): 1 match.
    // Closest first pairs g1-p0 (1 px), then g0-p1 (4.5 px): 2 matches.
    const std::vector<StemPoint> gt{{"a", 0, 0}, {"a", 4, 0}};
    const std::vector<StemPoint> pred{{"a", 3, 0}, {"a", -4.5, 0}};
    const auto r = match(gt, pred);
    EXPECT_EQ(r.true_positives, 2);
    EXPECT_DOUBLE_EQ(r.mean_error_mm, (1.0 + 4.5) / 2);
}

TEST(EvalMatch, OneToOneWhenTwoPredictionsAreNearOneStem)
{
    const std::vector<StemPoint> gt{{"a", 0, 0}};
    const std::vector<StemPoint> pred{{"a", 2, 0}, {"a", 1, 0}};
    const auto r = match(gt, pred);
    EXPECT_EQ(r.true_positives, 1);
    EXPECT_EQ(r.predictions, 2);
    EXPECT_DOUBLE_EQ(r.precision, 0.5);
    EXPECT_DOUBLE_EQ(r.recall, 1.0);
    EXPECT_DOUBLE_EQ(r.mean_error_mm, 1.0);  // the closer one is used
}

TEST(EvalMatch, OneToOneWhenOnePredictionIsNearTwoStems)
{
    const std::vector<StemPoint> gt{{"a", 0, 0}, {"a", 4, 0}};
    const std::vector<StemPoint> pred{{"a", 2, 0}};
    const auto r = match(gt, pred);
    EXPECT_EQ(r.true_positives, 1);
    EXPECT_DOUBLE_EQ(r.precision, 1.0);
    EXPECT_DOUBLE_EQ(r.recall, 0.5);
}

TEST(EvalMatch, EqualDistancesGoToTheLowerGroundTruthIndex)
{
    // p0 is 2 px from both stems. The first stem takes it; the second then
    // gets p2 (3 px), p1 stays unmatched: errors 2 and 3.
    const std::vector<StemPoint> pred{{"a", 2, 0}, {"a", -2.5, 0}, {"a", 7, 0}};
    auto r = match({{"a", 0, 0}, {"a", 4, 0}}, pred);
    EXPECT_EQ(r.true_positives, 2);
    EXPECT_DOUBLE_EQ(r.mean_error_mm, 2.5);
    // The same stems in the other order: (4,0) takes p0, (0,0) then gets p1 (2.5 px).
    r = match({{"a", 4, 0}, {"a", 0, 0}}, pred);
    EXPECT_EQ(r.true_positives, 2);
    EXPECT_DOUBLE_EQ(r.mean_error_mm, 2.25);
}

TEST(EvalMatch, EqualDistancesGoToTheLowerPredictionIndex)
{
    // Both predictions are 2 px from g0; only (-2,0) also reaches g1 (3 px).
    const std::vector<StemPoint> gt{{"a", 0, 0}, {"a", -5, 0}};
    auto r = match(gt, {{"a", 2, 0}, {"a", -2, 0}});  // g0 takes (2,0), g1 gets (-2,0)
    EXPECT_EQ(r.true_positives, 2);
    EXPECT_DOUBLE_EQ(r.mean_error_mm, 2.5);
    r = match(gt, {{"a", -2, 0}, {"a", 2, 0}});  // g0 takes (-2,0), g1 gets nothing
    EXPECT_EQ(r.true_positives, 1);
    EXPECT_DOUBLE_EQ(r.mean_error_mm, 2.0);
}

TEST(EvalMatch, ImagesAreKeptSeparate)
{
    // The same coordinates in another image never match.
    const std::vector<StemPoint> gt{{"a", 0, 0}, {"b", 100, 100}};
    const std::vector<StemPoint> pred{{"b", 0, 0}, {"a", 100, 100}};
    const auto r = match(gt, pred);
    EXPECT_EQ(r.true_positives, 0);

    // Interleaved input order; each image still matched on its own.
    const std::vector<StemPoint> gt2{{"a", 0, 0}, {"b", 0, 0}, {"a", 50, 0}, {"b", 50, 0}};
    const std::vector<StemPoint> pred2{{"b", 51, 0}, {"a", 1, 0}, {"b", 20, 0}};
    const auto r2 = match(gt2, pred2);
    EXPECT_EQ(r2.true_positives, 2);
    EXPECT_DOUBLE_EQ(r2.precision, 2.0 / 3.0);
    EXPECT_DOUBLE_EQ(r2.recall, 0.5);
    EXPECT_DOUBLE_EQ(r2.mean_error_mm, 1.0);
}

TEST(EvalMatch, ImageOnlyInOneListCountsAllItsPointsUnmatched)
{
    const std::vector<StemPoint> gt{{"a", 0, 0}, {"gt-only", 0, 0}, {"gt-only", 9, 9}};
    const std::vector<StemPoint> pred{{"a", 0, 0}, {"pred-only", 0, 0}};
    const auto r = match(gt, pred);
    EXPECT_EQ(r.ground_truth, 3);
    EXPECT_EQ(r.predictions, 2);
    EXPECT_EQ(r.true_positives, 1);
    EXPECT_DOUBLE_EQ(r.precision, 0.5);
    EXPECT_DOUBLE_EQ(r.recall, 1.0 / 3.0);
    EXPECT_DOUBLE_EQ(r.f1, 2.0 / 5.0);  // 2 TP / (GT + PRED)
}

TEST(EvalMatch, ImageNamesAreExactStrings)
{
    const auto r = match({{"rgb/000.png", 0, 0}}, {{"000.png", 0, 0}});
    EXPECT_EQ(r.true_positives, 0);
}

TEST(EvalMatch, ZeroDenominatorsGiveZeroNotNaN)
{
    const std::vector<StemPoint> some{{"a", 0, 0}};
    const std::vector<StemPoint> none;

    auto r = match(some, none);  // no predictions
    EXPECT_EQ(r.precision, 0.0);
    EXPECT_EQ(r.recall, 0.0);
    EXPECT_EQ(r.f1, 0.0);
    EXPECT_EQ(r.mean_error_mm, 0.0);

    r = match(none, some);  // no ground truth
    EXPECT_EQ(r.predictions, 1);
    EXPECT_EQ(r.precision, 0.0);
    EXPECT_EQ(r.recall, 0.0);
    EXPECT_EQ(r.f1, 0.0);

    r = match(none, none);
    EXPECT_EQ(r.ground_truth, 0);
    EXPECT_EQ(r.predictions, 0);
    EXPECT_EQ(r.precision, 0.0);
    EXPECT_EQ(r.recall, 0.0);
    EXPECT_EQ(r.f1, 0.0);
    EXPECT_EQ(r.mean_error_mm, 0.0);

    r = match(some, {{"a", 100, 0}});  // both nonzero, no match: P = R = 0, F1 = 0
    EXPECT_EQ(r.true_positives, 0);
    EXPECT_EQ(r.f1, 0.0);
    EXPECT_FALSE(std::isnan(r.f1));
}

TEST(EvalMatch, InvalidToleranceOrGsdMatchesNothing)
{
    const std::vector<StemPoint> pts{{"a", 0, 0}};
    for (const double bad : {0.0, -1.0, std::nan(""), HUGE_VAL}) {
        EXPECT_EQ(match(pts, pts, bad, kGsd).true_positives, 0) << bad;
        EXPECT_EQ(match(pts, pts, kTol, bad).true_positives, 0) << bad;
        const auto r = match(pts, pts, bad, bad);
        EXPECT_EQ(r.ground_truth, 1);
        EXPECT_EQ(r.precision, 0.0);
        EXPECT_EQ(r.mean_error_mm, 0.0);
    }
}

// --- read_stem_points --------------------------------------------------------

class EvalRead : public stemd::test::TempDirTest {
protected:

    fs::path write(const std::string& name, const std::string& text)
    {
        const auto path = dir_ / name;
        std::ofstream(path) << text;
        return path;
    }
};

TEST_F(EvalRead, GroundTruthColumnsByHeader)
{
    const auto path = write("stems.csv", "image,x,y,kind,leaves\n"
                                         "rgb/000.png,10.5,20,crop,4\n"
                                         "\n"
                                         "\"dir,with,commas/001.png\", 3 ,-4.25,weed,2\n");
    std::string error;
    const auto pts = read_stem_points(path, error);
    ASSERT_TRUE(pts) << error;
    ASSERT_EQ(pts->size(), 2u);
    EXPECT_EQ((*pts)[0].image, "rgb/000.png");
    EXPECT_EQ((*pts)[0].x_px, 10.5);
    EXPECT_EQ((*pts)[0].y_px, 20.0);
    EXPECT_EQ((*pts)[1].image, "dir,with,commas/001.png");
    EXPECT_EQ((*pts)[1].x_px, 3.0);
    EXPECT_EQ((*pts)[1].y_px, -4.25);
}

TEST_F(EvalRead, DetectionColumnsByHeader)
{
    const auto path = write("pred.csv", "image,plant,x,y,method,leaves,area_px\n"
                                        "000.png,0,1.250,2.500,leaves,3,1200\n");
    std::string error;
    const auto pts = read_stem_points(path, error);
    ASSERT_TRUE(pts) << error;
    ASSERT_EQ(pts->size(), 1u);
    EXPECT_EQ((*pts)[0].image, "000.png");
    EXPECT_EQ((*pts)[0].x_px, 1.25);
    EXPECT_EQ((*pts)[0].y_px, 2.5);
}

TEST_F(EvalRead, HeaderOnlyIsEmptyList)
{
    std::string error;
    const auto pts = read_stem_points(write("e.csv", "image,x,y\n"), error);
    ASSERT_TRUE(pts) << error;
    EXPECT_TRUE(pts->empty());
}

TEST_F(EvalRead, BadNumberNamesFileAndLine)
{
    const auto path = write("bad.csv", "image,x,y\na,1,2\nb,3,2x\n");
    std::string error;
    EXPECT_FALSE(read_stem_points(path, error));
    EXPECT_EQ(error, path.string() + ":3: y '2x' is not a finite number");
}

TEST_F(EvalRead, NonFiniteAndEmptyNumbersAreRejected)
{
    for (const std::string bad : {"nan", "inf", "-inf", "", " ", "1e999"}) {
        const auto path = write("nf.csv", "image,x,y\na," + bad + ",2\n");
        std::string error;
        EXPECT_FALSE(read_stem_points(path, error)) << bad;
        EXPECT_EQ(error, path.string() + ":2: x '" + bad + "' is not a finite number");
    }
}

TEST_F(EvalRead, MissingColumnNamesFileAndHeader)
{
    const auto path = write("nocol.csv", "image,plant,x,method\na,0,1,leaves\n");
    std::string error;
    EXPECT_FALSE(read_stem_points(path, error));
    EXPECT_EQ(error, path.string() + ": header has no column 'y' (columns: image,plant,x,method)");
}

TEST_F(EvalRead, EmptyImageNameNamesLine)
{
    const auto path = write("noimg.csv", "image,x,y\na,1,2\n,3,4\n");
    std::string error;
    EXPECT_FALSE(read_stem_points(path, error));
    EXPECT_EQ(error, path.string() + ":3: image is empty");
}

TEST_F(EvalRead, WrongFieldCountAndMissingFile)
{
    std::string error;
    const auto path = write("short.csv", "image,x,y\na,1\n");
    EXPECT_FALSE(read_stem_points(path, error));
    EXPECT_EQ(error.rfind(path.string() + ":2: ", 0), 0u) << error;

    EXPECT_FALSE(read_stem_points(dir_ / "missing.csv", error));
    EXPECT_EQ(error, (dir_ / "missing.csv").string() + ": cannot open: No such file or directory (errno 2)");
}

// --- mask_iou ----------------------------------------------------------------

TEST(EvalIou, KnownIntersectionAndUnion)
{
    // 10x10: prediction columns 0-5 (60 px), truth columns 4-9 (60 px);
    // intersection columns 4-5 (20 px), union all 100 px.
    cv::Mat pred(10, 10, CV_8UC1, cv::Scalar(0)), gt(10, 10, CV_8UC1, cv::Scalar(0));
    pred.colRange(0, 6).setTo(255);
    gt.colRange(4, 10).setTo(255);
    std::string error;
    const auto r = mask_iou(pred, gt, error);
    ASSERT_TRUE(r) << error;
    EXPECT_EQ(r->intersection_px, 20);
    EXPECT_EQ(r->union_px, 100);
    EXPECT_DOUBLE_EQ(r->iou, 0.2);
}

TEST(EvalIou, AnyNonzeroIsVegetation)
{
    // 1 & 2 == 0 bitwise, but both are vegetation.
    cv::Mat pred(4, 4, CV_8UC1, cv::Scalar(0)), gt(4, 4, CV_8UC1, cv::Scalar(0));
    pred(cv::Rect(0, 0, 2, 2)).setTo(1);
    gt(cv::Rect(0, 0, 2, 1)).setTo(2);
    gt(cv::Rect(3, 3, 1, 1)).setTo(7);
    std::string error;
    const auto r = mask_iou(pred, gt, error);
    ASSERT_TRUE(r) << error;
    EXPECT_EQ(r->intersection_px, 2);
    EXPECT_EQ(r->union_px, 5);
    EXPECT_DOUBLE_EQ(r->iou, 0.4);
}

TEST(EvalIou, IdenticalDisjointAndEmpty)
{
    cv::Mat a(8, 6, CV_8UC1, cv::Scalar(0)), b(8, 6, CV_8UC1, cv::Scalar(0));
    a.rowRange(0, 3).setTo(255);
    b.rowRange(5, 8).setTo(255);
    std::string error;
    auto r = mask_iou(a, a, error);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->iou, 1.0);
    r = mask_iou(a, b, error);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->intersection_px, 0);
    EXPECT_EQ(r->union_px, 36);
    EXPECT_EQ(r->iou, 0.0);

    const cv::Mat none(8, 6, CV_8UC1, cv::Scalar(0));
    r = mask_iou(none, none, error);  // no vegetation in either: perfect agreement
    ASSERT_TRUE(r);
    EXPECT_EQ(r->union_px, 0);
    EXPECT_EQ(r->iou, 1.0);
}

TEST(EvalIou, NonContinuousRoi)
{
    cv::Mat big(20, 20, CV_8UC1, cv::Scalar(255));
    cv::Mat pred = big(cv::Rect(5, 5, 4, 4));  // all vegetation, not continuous
    cv::Mat gt(4, 4, CV_8UC1, cv::Scalar(0));
    gt.row(0).setTo(255);
    std::string error;
    const auto r = mask_iou(pred, gt, error);
    ASSERT_TRUE(r) << error;
    EXPECT_EQ(r->intersection_px, 4);
    EXPECT_EQ(r->union_px, 16);
}

TEST(EvalIou, SizeMismatchIsAnError)
{
    const cv::Mat pred(10, 12, CV_8UC1, cv::Scalar(0)), gt(10, 10, CV_8UC1, cv::Scalar(0));
    std::string error;
    EXPECT_FALSE(mask_iou(pred, gt, error));
    EXPECT_EQ(error, "mask sizes differ: predicted 12x10 CV_8UC1, ground truth 10x10 CV_8UC1");
}

TEST(EvalIou, WrongTypeOrEmptyIsAnError)
{
    const cv::Mat gray(4, 4, CV_8UC1, cv::Scalar(0)), color(4, 4, CV_8UC3, cv::Scalar(0, 0, 0));
    std::string error;
    EXPECT_FALSE(mask_iou(color, gray, error));
    EXPECT_NE(error.find("CV_8UC3"), std::string::npos) << error;
    EXPECT_FALSE(mask_iou(gray, cv::Mat(), error));
    EXPECT_EQ(error, "ground-truth mask is empty");
    EXPECT_FALSE(mask_iou(cv::Mat(), gray, error));
    EXPECT_EQ(error, "predicted mask is empty");
}

// --- class_map_score -----------------------------------------------------------

TEST(EvalClasses, CountsEachAnnotatedPixelByTheClassTheMapGivesIt)
{
    // Truth, one row of 10: 4 crop, 4 weed, 2 soil (and one value 7 that is
    // no class, not scored). The map: crop pixels 2 right, 1 weed, 1 soil;
    // weed pixels 1 right, 2 crop, 1 soil; whatever it says on soil is not
    // scored.
    const std::uint8_t truth_row[] = {1, 1, 1, 1, 2, 2, 2, 2, 0, 7};
    const std::uint8_t map_row[] = {1, 1, 2, 0, 2, 1, 1, 0, 2, 1};
    const cv::Mat truth(1, 10, CV_8UC1, const_cast<std::uint8_t*>(truth_row));
    const cv::Mat map(1, 10, CV_8UC1, const_cast<std::uint8_t*>(map_row));
    std::string error;
    const auto s = stemd::eval::class_map_score(map, truth, error);
    ASSERT_TRUE(s) << error;
    EXPECT_EQ(s->crop_px, 4);
    EXPECT_EQ(s->weed_px, 4);
    EXPECT_EQ(s->crop_right, 2);
    EXPECT_EQ(s->crop_as_weed, 1);
    EXPECT_EQ(s->crop_as_soil(), 1);
    EXPECT_EQ(s->weed_right, 1);
    EXPECT_EQ(s->weed_as_crop, 2);
    EXPECT_EQ(s->weed_as_soil(), 1);
    EXPECT_DOUBLE_EQ(s->crop_recall(), 0.5);
    EXPECT_DOUBLE_EQ(s->weed_recall(), 0.25);
    EXPECT_DOUBLE_EQ(s->balanced_accuracy(), 0.375);
}

TEST(EvalClasses, FramesPoolTheirPixelsAndAMissingClassLeavesTheOtherRecall)
{
    stemd::eval::ClassScore only_crop;
    only_crop.crop_px = 10;
    only_crop.crop_right = 9;
    EXPECT_DOUBLE_EQ(only_crop.balanced_accuracy(), 0.9) << "no weed annotated: the crop recall alone";
    EXPECT_DOUBLE_EQ(stemd::eval::ClassScore{}.balanced_accuracy(), 1.0) << "nothing annotated, nothing wrong";

    stemd::eval::ClassScore only_weed;
    only_weed.weed_px = 30;
    only_weed.weed_right = 15;
    only_weed.weed_as_crop = 5;
    stemd::eval::ClassScore all = only_crop;
    all += only_weed;
    EXPECT_EQ(all.crop_px, 10);
    EXPECT_EQ(all.weed_px, 30);
    EXPECT_EQ(all.weed_as_soil(), 10);
    // Pooled over pixels, as stemd-train reports it: (0.9 + 0.5) / 2, not
    // the mean of the frames' own figures (0.9 and 0.5 either way here).
    EXPECT_DOUBLE_EQ(all.balanced_accuracy(), 0.7);
}

TEST(EvalClasses, ANonClassValueOrMismatchedMapsAreErrors)
{
    cv::Mat map(2, 3, CV_8UC1, cv::Scalar(0)), truth(2, 3, CV_8UC1, cv::Scalar(1));
    map.at<std::uint8_t>(1, 2) = 255;
    std::string error;
    EXPECT_FALSE(stemd::eval::class_map_score(map, truth, error));
    EXPECT_EQ(error, "predicted class map holds 255 at (2, 1): not 0 soil, 1 crop or 2 weed");
    EXPECT_FALSE(stemd::eval::class_map_score(cv::Mat(2, 4, CV_8UC1, cv::Scalar(0)), truth, error));
    EXPECT_EQ(error, "class map sizes differ: predicted 4x2 CV_8UC1, ground truth 3x2 CV_8UC1");
    EXPECT_FALSE(stemd::eval::class_map_score(cv::Mat(2, 3, CV_8UC3, cv::Scalar(0, 0, 0)), truth, error));
    EXPECT_EQ(error, "class maps must be 8-bit single-channel (CV_8UC1): predicted 3x2 CV_8UC3, ground truth 3x2 CV_8UC1");
    EXPECT_FALSE(stemd::eval::class_map_score(cv::Mat(), truth, error));
    EXPECT_EQ(error, "predicted class map is empty");
}

}  // namespace
