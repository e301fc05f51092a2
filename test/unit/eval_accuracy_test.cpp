// Accuracy regression on fixed synthetic frames: the leaf method must beat
// the centre of mass where leaves are distinct (the paper's claim ii), and
// neither may fall below a floor set well under today's figures.
#include <gtest/gtest.h>

#include <memory>

#include "stemd/eval/eval.hpp"
#include "stemd/synth/synth.hpp"
#include "stemd/vision/detect.hpp"

using namespace stemd;

namespace {

struct Scores {
    eval::MatchResult leaves, com;
    double mean_iou = 0;
};

Scores score(synth::Preset preset, int frames)
{
    synth::Options options;
    options.preset = preset;
    options.seed = 424242;  // not a seed the tools or the benchmark use
    std::vector<eval::StemPoint> truth, from_leaves, from_com;
    vision::Params params;  // the documented defaults
    auto detections = std::make_unique<vision::Detections>();
    std::unique_ptr<vision::Workspace> ws;
    Scores s;
    for (int i = 0; i < frames; ++i) {
        const synth::Frame f = synth::generate_frame(options, i);
        const std::string name = std::to_string(i);
        for (const auto& stem : f.stems)
            truth.push_back({name, stem.x_px, stem.y_px});
        if (!ws)
            ws = std::make_unique<vision::Workspace>(f.bgr.size(), params);
        for (const auto method : {vision::StemMethod::leaves, vision::StemMethod::com}) {
            params.stem_method = method;
            vision::detect({.bgr = f.bgr}, params, *ws, *detections);
            EXPECT_EQ(detections->status, vision::DetectStatus::ok);
            for (const auto& p : detections->plants)
                (method == vision::StemMethod::leaves ? from_leaves : from_com).push_back({name, p.stem.x, p.stem.y});
        }
        cv::Mat vegetation;
        vision::unpack_mask(ws->vegetation(), vegetation);
        std::string error;
        const auto iou = eval::mask_iou(vegetation, f.mask, error);
        EXPECT_TRUE(iou.has_value()) << error;
        s.mean_iou += iou ? iou->iou / frames : 0;
    }
    s.leaves = eval::match_stems(truth, from_leaves, 5.0, params.gsd_mm_per_px);
    s.com = eval::match_stems(truth, from_com, 5.0, params.gsd_mm_per_px);
    return s;
}

}  // namespace

TEST(Accuracy, LateStageLeavesBeatTheCentreOfMass)
{
    const Scores s = score(synth::Preset::late, 8);
    EXPECT_GT(s.leaves.recall, s.com.recall + 0.05);
    EXPECT_GT(s.leaves.precision, s.com.precision + 0.05);
    EXPECT_GE(s.leaves.recall, 0.65);
    EXPECT_GE(s.leaves.precision, 0.60);
    EXPECT_LT(s.leaves.mean_error_mm, 3.0);
    EXPECT_GE(s.mean_iou, 0.85);
}

TEST(Accuracy, DenseFieldLeavesBeatTheCentreOfMass)
{
    const Scores s = score(synth::Preset::dense, 6);
    EXPECT_GT(s.leaves.recall, s.com.recall + 0.05);
    EXPECT_GT(s.leaves.precision, s.com.precision + 0.03);
    EXPECT_GE(s.leaves.recall, 0.70);
    EXPECT_GE(s.leaves.precision, 0.50);
}
