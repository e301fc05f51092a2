// The detector with the shipped configuration on real field frames in
// ../shared/data (or STEMD_REAL_DATA). The data is not part of the
// repository (its licences forbid copying it): without it every test here
// is skipped with the reason.
#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <span>
#include <utility>
#include <string>
#include <tuple>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "stemd/eval/eval.hpp"
#include "stemd/io/csv.hpp"
#include "stemd/io/recording.hpp"
#include "stemd/config/config.hpp"
#include "stemd/vision/detect.hpp"

namespace fs = std::filesystem;
using namespace stemd;

namespace {

fs::path real_data_dir()
{
    if (const char* dir = std::getenv("STEMD_REAL_DATA"))
        return dir;
    return fs::path(STEMD_SOURCE_DIR) / ".." / "shared" / "data";
}

// Skips the calling test when `set` is not there.
#define REQUIRE_REAL_SET(set)                                                                                       \
    do {                                                                                                            \
        if (!fs::exists(real_data_dir() / (set)))                                                                   \
            GTEST_SKIP() << "real data set " << (real_data_dir() / (set)).string()                                 \
                         << " is absent (set STEMD_REAL_DATA to the folder holding bonirob/, carrot-dev/, "        \
                            "cwfid-train/)";                                                                        \
    } while (0)

// The shipped configuration (config/stemd.yaml) with `overrides`.
vision::Params shipped_params(const std::vector<std::string>& overrides)
{
    config::Config config;
    const auto error = config.load_file(fs::path(STEMD_SOURCE_DIR) / "config" / "stemd.yaml");
    EXPECT_FALSE(error) << error->to_string();
    for (const std::string& set : overrides) {
        const auto bad = config.set_override(set);
        EXPECT_FALSE(bad) << set;
    }
    return config.settings().daemon.vision;
}

cv::Mat read(const fs::path& path, int flags)
{
    cv::Mat image = cv::imread(path.string(), flags);
    EXPECT_FALSE(image.empty()) << path;
    return image;
}

// IoU of the detector's vegetation mask against a human mask (255 = vegetation).
double frame_iou(const cv::Mat& bgr, const cv::Mat& truth, const vision::Params& params)
{
    vision::Workspace workspace(bgr.size(), params);
    vision::Detections detections;
    vision::detect({.bgr = bgr}, params, workspace, detections);
    cv::Mat predicted;
    vision::unpack_mask(workspace.vegetation(), predicted);
    std::string error;
    const auto iou = eval::mask_iou(predicted, truth, error);
    EXPECT_TRUE(iou) << error;
    return iou ? iou->iou : 0;
}

// A frame as another light or a noisier sensor gives it: every value times
// the exposure and its channel's gain (B, G, R: a colour cast of the light
// or of the white balance), plus Gaussian noise of noise_dn digital
// numbers (read and gain noise), rounded and saturated to 8 bits, as
// tools/perturb-recording.py does to a recording.
struct Light {
    double exposure = 1;
    cv::Scalar gains = cv::Scalar::all(1);
    double noise_dn = 0;
    double corner_light = 1;  // vignetting: the corners' share of the centre's light
    bool yuyv = false;        // through a camera's YUYV (4:2:2) and the V4L2 source's decode
};

// An 8-bit BGR frame as a YUYV camera delivers it to the V4L2 source: BT.601
// limited range, each horizontal pair of pixels sharing its mean U and V,
// decoded by COLOR_YUV2BGR_YUYV (as tools/perturb-recording.py --yuyv).
cv::Mat through_yuyv(const cv::Mat& bgr)
{
    const int even = bgr.cols - bgr.cols % 2;
    cv::Mat packed(bgr.rows, even, CV_8UC2);
    for (int y = 0; y < bgr.rows; ++y) {
        const cv::Vec3b* px = bgr.ptr<cv::Vec3b>(y);
        cv::Vec2b* out = packed.ptr<cv::Vec2b>(y);
        for (int x = 0; x < even; x += 2) {
            double u = 0, v = 0;
            for (int k = 0; k < 2; ++k) {
                const double b = px[x + k][0], g = px[x + k][1], r = px[x + k][2];
                out[x + k][0] = cv::saturate_cast<std::uint8_t>(16 + (65.481 * r + 128.553 * g + 24.966 * b) / 255);
                u += (128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255) / 2;
                v += (128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255) / 2;
            }
            out[x][1] = cv::saturate_cast<std::uint8_t>(u);
            out[x + 1][1] = cv::saturate_cast<std::uint8_t>(v);
        }
    }
    cv::Mat out = bgr.clone();
    if (even > 0) {
        cv::Mat decoded;
        cv::cvtColor(packed, decoded, cv::COLOR_YUV2BGR_YUYV);
        decoded.copyTo(out(cv::Rect(0, 0, even, bgr.rows)));
    }
    return out;
}

// A lens's natural falloff, cos^4 of the field angle, whose tangent grows
// linearly from the centre, scaled to `corner_light` at the corners (as
// tools/perturb-recording.py --vignetting).
cv::Mat falloff(cv::Size size, double corner_light)
{
    cv::Mat field(size, CV_32F);
    const double cx = (size.width - 1) / 2.0, cy = (size.height - 1) / 2.0;
    const double half_diagonal_sq = std::max(cx * cx + cy * cy, 1.0);
    const double a = 1.0 / std::sqrt(corner_light) - 1.0;
    for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
            const double rho_sq = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / half_diagonal_sq;
            field.at<float>(y, x) = static_cast<float>(1.0 / ((1.0 + a * rho_sq) * (1.0 + a * rho_sq)));
        }
    return field;
}

cv::Mat under(const cv::Mat& image, const Light& light, cv::RNG& rng)
{
    if (light.exposure == 1 && light.gains == cv::Scalar::all(1) && light.noise_dn == 0 && light.corner_light == 1 &&
        !light.yuyv)
        return image;
    cv::Mat values;
    image.convertTo(values, CV_32F);
    values = values.mul(cv::Scalar::all(light.exposure).mul(image.channels() == 3 ? light.gains : cv::Scalar::all(1)));
    if (light.corner_light < 1) {
        cv::Mat field = falloff(image.size(), light.corner_light);
        if (image.channels() == 3)
            cv::merge(std::vector<cv::Mat>{field, field, field}, field);
        values = values.mul(field);
    }
    if (light.noise_dn > 0) {
        cv::Mat noise(values.size(), values.type());
        rng.fill(noise, cv::RNG::NORMAL, 0.0, light.noise_dn);
        values += noise;
    }
    cv::Mat out;
    values.convertTo(out, CV_8U);
    return light.yuyv && out.channels() == 3 ? through_yuyv(out) : out;
}

// Mean IoU over the frames of a recording whose mask column holds the
// human masks (255 = vegetation), each frame under `light`.
double mean_mask_iou(const fs::path& recording_dir, const vision::Params& params, const Light& light = {})
{
    std::string error;
    const auto recording = io::read_recording(recording_dir, error);
    EXPECT_TRUE(recording) << error;
    if (!recording || recording->frames.empty())
        return 0;
    cv::RNG rng(1);
    double sum = 0;
    for (const io::RecordingFrame& frame : recording->frames)
        sum += frame_iou(under(read(recording->resolve(frame.rgb), cv::IMREAD_COLOR), light, rng),
                         read(recording->resolve(frame.mask), cv::IMREAD_GRAYSCALE), params);
    return sum / static_cast<double>(recording->frames.size());
}

// CWFID's training frames (images/NNN_image.png, masks/NNN_mask.png with
// 0 = vegetation).
double cwfid_mean_iou(const vision::Params& params, const Light& light = {})
{
    const fs::path dir = real_data_dir() / "cwfid-train";
    // In name order, so that each frame gets the same noise on every file system.
    std::vector<fs::path> images;
    for (const auto& entry : fs::directory_iterator(dir / "images"))
        images.push_back(entry.path());
    std::sort(images.begin(), images.end());
    cv::RNG rng(1);
    double sum = 0;
    int frames = 0;
    for (const fs::path& image : images) {
        const std::string name = image.filename().string();
        const auto cut = name.find("_image.png");
        if (cut == std::string::npos)
            continue;
        const cv::Mat truth = read(dir / "masks" / (name.substr(0, cut) + "_mask.png"), cv::IMREAD_GRAYSCALE) == 0;
        sum += frame_iou(under(read(image, cv::IMREAD_COLOR), light, rng), truth, params);
        ++frames;
    }
    EXPECT_GT(frames, 0);
    return frames ? sum / frames : 0;
}

struct BoniRobFrame {
    std::string name;
    cv::Mat bgr;
    cv::Mat nir;
};

std::vector<BoniRobFrame> bonirob_frames()
{
    const fs::path dir = real_data_dir() / "bonirob";
    std::vector<BoniRobFrame> frames;
    for (int i = 0; i < 3; ++i) {
        char rgb[32], nir[32];
        std::snprintf(rgb, sizeof rgb, "rgb_%05d.png", i);
        std::snprintf(nir, sizeof nir, "nir_%05d.png", i);
        frames.push_back({rgb, read(dir / rgb, cv::IMREAD_COLOR), read(dir / nir, cv::IMREAD_GRAYSCALE)});
    }
    return frames;
}

constexpr double kBoniRobGsdMmPerPx = 0.395;  // measured from the plants' motion (data README)

std::vector<eval::StemPoint> detect_stems(const std::vector<BoniRobFrame>& frames, const vision::Params& params)
{
    std::vector<eval::StemPoint> stems;
    for (const BoniRobFrame& frame : frames) {
        const vision::Detections d = vision::detect({.bgr = frame.bgr, .nir = frame.nir}, params);
        EXPECT_EQ(d.status, vision::DetectStatus::ok) << frame.name;
        for (const vision::Plant& plant : d.plants)
            if (plant.has_stem)
                stems.push_back({frame.name, plant.stem.x, plant.stem.y});
    }
    return stems;
}

std::vector<eval::StemPoint> bonirob_truth()
{
    std::string error;
    const auto truth = eval::read_stem_points(real_data_dir() / "bonirob" / "stems.csv", error);
    EXPECT_TRUE(truth) << error;
    return truth.value_or(std::vector<eval::StemPoint>{});
}

// At least one of the frame's annotated stems has a reported stem within 5 mm.
void expect_a_stem_within_5mm(const BoniRobFrame& frame, const std::vector<eval::StemPoint>& truth,
                              const vision::Params& params)
{
    std::vector<eval::StemPoint> frame_truth;
    for (const auto& t : truth)
        if (t.image == frame.name)
            frame_truth.push_back(t);
    const auto stems = detect_stems({frame}, params);
    const auto match = eval::match_stems(frame_truth, stems, 5.0, kBoniRobGsdMmPerPx);
    EXPECT_GE(match.true_positives, 1) << frame.name << ": " << stems.size() << " stems reported";
}

}  // namespace

TEST(RealFrames, BoniRobRgbFindsAPlantWithItsStemInEveryFrame)
{
    // The shipped configuration once called these frames bare soil: Otsu
    // split the soil (1 % vegetation) and the frame was thrown away.
    REQUIRE_REAL_SET("bonirob");
    const auto frames = bonirob_frames();
    const auto truth = bonirob_truth();
    const auto params = shipped_params({"camera.gsd_mm_per_px=0.395", "segment.method=chromatic_exg"});
    for (const BoniRobFrame& frame : frames) {
        expect_a_stem_within_5mm(frame, truth, params);
    }
}

TEST(RealFrames, BoniRobRgbAndNirFindsEveryAnnotatedStemWithin5mm)
{
    REQUIRE_REAL_SET("bonirob");
    const auto stems =
        detect_stems(bonirob_frames(), shipped_params({"camera.gsd_mm_per_px=0.395", "segment.method=ndvi"}));
    const auto truth = bonirob_truth();
    const auto match = eval::match_stems(truth, stems, 5.0, kBoniRobGsdMmPerPx);
    EXPECT_EQ(match.true_positives, static_cast<int>(truth.size())) << stems.size() << " stems reported";
}

// Green and bright in NIR together: every annotated stem within 5 mm, and
// none of the NIR-bright dead matter that NDVI alone reports (checked by eye:
// reddish in RGB, bright in NIR) in frame 1 at (101, 473) and frame 2 at
// (191, 502). The weed seedlings NDVI finds (green and NIR-bright, e.g.
// frame 1 at (858, 703)) stay.
TEST(RealFrames, BoniRobExgAndNdviFindsTheStemsAndNotDeadMatter)
{
    REQUIRE_REAL_SET("bonirob");
    const auto params = shipped_params({"camera.gsd_mm_per_px=0.395", "segment.method=exg_and_ndvi"});
    const auto stems = detect_stems(bonirob_frames(), params);
    const auto truth = bonirob_truth();
    const auto match = eval::match_stems(truth, stems, 5.0, kBoniRobGsdMmPerPx);
    EXPECT_EQ(match.true_positives, static_cast<int>(truth.size())) << stems.size() << " stems reported";
    const std::vector<eval::StemPoint> dead{{"rgb_00001.png", 101, 473}, {"rgb_00002.png", 191, 502}};
    EXPECT_EQ(eval::match_stems(dead, stems, 5.0, kBoniRobGsdMmPerPx).true_positives, 0);
    const std::vector<eval::StemPoint> weed{{"rgb_00001.png", 858, 703}};
    EXPECT_EQ(eval::match_stems(weed, stems, 5.0, kBoniRobGsdMmPerPx).true_positives, 1);
}

// stems.csv holds the sugar beets only. The other plants in these frames,
// checked by eye on RGB and NIR crops (the centre of each seedling, to the
// 10 mm used below): frame 0 (849, 70), a thin green seedling, bright and
// curved in NIR; frame 0 (1028, 85), a leaf blade with a rounded tip, green
// at the tip and bright in NIR (a cotyledon: straw has parallel edges and a
// square end); frame 2 (1216, 158), a seedling of three round leaves, green
// and NIR-bright; frame 2 (812, 270), a green leaf, NIR-bright. Not a plant:
// frame 0 (302, 724), beige straw with a green colour fringe along one
// edge, green only because the green plane is misregistered by a pixel
// (drop_colour_fringes). Everything RGB reports must be one of these plants.
TEST(RealFrames, BoniRobRgbReportsOnlyPlantsAndNotTheStrawsColourFringe)
{
    REQUIRE_REAL_SET("bonirob");
    const auto stems =
        detect_stems(bonirob_frames(), shipped_params({"camera.gsd_mm_per_px=0.395", "segment.method=chromatic_exg"}));
    std::vector<eval::StemPoint> plants = bonirob_truth();
    plants.insert(plants.end(), {{"rgb_00000.png", 849, 70},
                                 {"rgb_00000.png", 1028, 85},
                                 {"rgb_00002.png", 1216, 158},
                                 {"rgb_00002.png", 812, 270}});
    const std::vector<eval::StemPoint> straw{{"rgb_00000.png", 302, 724}};
    int on_plants = 0, on_straw = 0;
    for (const eval::StemPoint& stem : stems) {
        if (eval::match_stems(plants, std::span(&stem, 1), 10.0, kBoniRobGsdMmPerPx).true_positives == 1)
            ++on_plants;
        else if (eval::match_stems(straw, std::span(&stem, 1), 10.0, kBoniRobGsdMmPerPx).true_positives == 1)
            ++on_straw;
        else
            ADD_FAILURE() << stem.image << " (" << stem.x_px << ", " << stem.y_px << "): reported, and no plant is there";
    }
    EXPECT_EQ(on_straw, 0);
    // Precision over plants: the goal is 80 %.
    ASSERT_FALSE(stems.empty());
    EXPECT_GE(static_cast<double>(on_plants) / static_cast<double>(stems.size()), 0.8)
        << on_plants << " of " << stems.size() << " reports on plants";
}

// The shipped default (segment.method auto) on the same camera: with its
// NIR plane it reports what exg_and_ndvi reports, from RGB alone what
// chromatic_exg reports.
TEST(RealFrames, BoniRobDefaultTakesTheNirPlaneWhenTheFramesHaveOne)
{
    REQUIRE_REAL_SET("bonirob");
    const auto frames = bonirob_frames();
    std::vector<BoniRobFrame> rgb_only = frames;
    for (BoniRobFrame& frame : rgb_only)
        frame.nir = cv::Mat();
    const auto key = [](const std::vector<eval::StemPoint>& stems) {
        std::vector<std::tuple<std::string, double, double>> out;
        for (const auto& s : stems)
            out.emplace_back(s.image, s.x_px, s.y_px);
        return out;
    };
    const auto shipped = shipped_params({"camera.gsd_mm_per_px=0.395"});
    ASSERT_EQ(shipped.segmentation, vision::Segmentation::automatic);
    const auto with_nir = detect_stems(frames, shipped);
    EXPECT_EQ(key(with_nir),
              key(detect_stems(frames, shipped_params({"camera.gsd_mm_per_px=0.395", "segment.method=exg_and_ndvi"}))));
    EXPECT_EQ(key(detect_stems(rgb_only, shipped)),
              key(detect_stems(rgb_only, shipped_params({"camera.gsd_mm_per_px=0.395", "segment.method=chromatic_exg"}))));
    const auto truth = bonirob_truth();
    EXPECT_EQ(eval::match_stems(truth, with_nir, 5.0, kBoniRobGsdMmPerPx).true_positives, static_cast<int>(truth.size()));
}

// Bare soil stays bare: a region of frame 0 with no plant in it (checked by
// eye in RGB and NIR: dark clods, bright clods with colour fringes, a straw).
// Either index alone finds two "plants" there; both together find none.
TEST(RealFrames, BoniRobBareSoilHasNoPlantWithExgAndNdvi)
{
    REQUIRE_REAL_SET("bonirob");
    const BoniRobFrame frame = bonirob_frames().front();
    const cv::Rect bare(600, 300, 696, 400);
    const cv::Mat bgr = frame.bgr(bare).clone();
    const cv::Mat nir = frame.nir(bare).clone();
    const auto d = vision::detect({.bgr = bgr, .nir = nir},
                                  shipped_params({"camera.gsd_mm_per_px=0.395", "segment.method=exg_and_ndvi"}));
    ASSERT_EQ(d.status, vision::DetectStatus::ok);
    EXPECT_EQ(d.plants.size(), 0u);
}

// The same bare soil from RGB alone: the clods that look green in ExG there
// have more red than green (segment.leaf_colour).
TEST(RealFrames, BoniRobBareSoilHasNoPlantFromRgb)
{
    REQUIRE_REAL_SET("bonirob");
    const BoniRobFrame frame = bonirob_frames().front();
    const cv::Mat bgr = frame.bgr(cv::Rect(600, 300, 696, 400)).clone();
    const auto d = vision::detect({.bgr = bgr}, shipped_params({"camera.gsd_mm_per_px=0.395"}));
    ASSERT_EQ(d.status, vision::DetectStatus::ok);
    EXPECT_EQ(d.plants.size(), 0u);
}

TEST(RealFrames, CwfidMaskIouReachesTheGoalAndBeatsPlainExcessGreenWithOtsu)
{
    REQUIRE_REAL_SET("cwfid-train");
    const double shipped = cwfid_mean_iou(shipped_params({"camera.gsd_mm_per_px=0.11"}));
    const double plain = cwfid_mean_iou(shipped_params({"camera.gsd_mm_per_px=0.11", "segment.method=exg",
                                                        "segment.threshold=otsu", "segment.smooth=false",
                                                        "segment.opening_radius_px=0",
                                                        "segment.edge_radius_px=0"}));
    EXPECT_GE(shipped, 0.90);
    EXPECT_GT(shipped, plain + 0.01) << "shipped " << shipped << ", plain ExG + Otsu " << plain;
}

// CWFID's stems annotated by eye for this project (test/data, the rows
// marked sure: within about 5 px), against the stems the shipped
// configuration reports on cwfid-train, within 15 px (1.65 mm).
int cwfid_sure_stems_found(const std::vector<std::string>& overrides, int& annotated)
{
    std::string error;
    const auto table = io::read_csv(fs::path(STEMD_SOURCE_DIR) / "test" / "data" / "cwfid-train-stems.csv", error);
    EXPECT_TRUE(table) << error;
    std::vector<eval::StemPoint> sure;
    std::vector<std::string> images;
    if (table) {
        const int image = table->column("image"), x = table->column("x"), y = table->column("y"),
                  certain = table->column("sure");
        EXPECT_TRUE(image >= 0 && x >= 0 && y >= 0 && certain >= 0);
        for (const io::CsvTable::Row& row : table->rows)
            if (image >= 0 && x >= 0 && y >= 0 && certain >= 0 && row.fields[static_cast<std::size_t>(certain)] == "1")
                sure.push_back({row.fields[static_cast<std::size_t>(image)],
                                std::stod(row.fields[static_cast<std::size_t>(x)]),
                                std::stod(row.fields[static_cast<std::size_t>(y)])});
    }
    for (const eval::StemPoint& stem : sure)
        if (std::find(images.begin(), images.end(), stem.image) == images.end())
            images.push_back(stem.image);
    std::vector<std::string> settings{"camera.gsd_mm_per_px=0.11"};
    settings.insert(settings.end(), overrides.begin(), overrides.end());
    const vision::Params params = shipped_params(settings);
    std::vector<eval::StemPoint> stems;
    for (const std::string& image : images) {
        const vision::Detections d =
            vision::detect({.bgr = read(real_data_dir() / "cwfid-train" / "images" / image, cv::IMREAD_COLOR)}, params);
        for (const vision::Plant& plant : d.plants)
            if (plant.has_stem)
                stems.push_back({image, plant.stem.x, plant.stem.y});
    }
    annotated = static_cast<int>(sure.size());
    return eval::match_stems(sure, stems, 1.65, 0.11).true_positives;
}

TEST(RealFrames, CwfidNeighbouringPlantsKeepTheirOwnStems)
{
    // CWFID's plants grow a few mm apart, within the group gap. Joining
    // every piece the gap reaches put 22 of the 107 sure stems within
    // 15 px; a piece with leaves of its own now stays a plant. A floor
    // while the goal (11 of 12) is open: most of what is left are plants
    // that touch (one piece) and stems more than 15 px off.
    REQUIRE_REAL_SET("cwfid-train");
    int annotated = 0;
    const int found = cwfid_sure_stems_found({}, annotated);
    EXPECT_EQ(annotated, 107);
    EXPECT_GE(found, 30) << "of " << annotated;
    int annotated_com = 0;
    const int centre_of_mass = cwfid_sure_stems_found({"stem.method=com"}, annotated_com);
    EXPECT_GE(found, centre_of_mass);
}

TEST(RealFrames, MixedEdgePixelsRaiseTheMaskIouOnBothSets)
{
    // The edge step's own gain, with everything else as shipped.
    REQUIRE_REAL_SET("cwfid-train");
    REQUIRE_REAL_SET("carrot-dev");
    const double cwfid_with = cwfid_mean_iou(shipped_params({"camera.gsd_mm_per_px=0.11"}));
    const double cwfid_without =
        cwfid_mean_iou(shipped_params({"camera.gsd_mm_per_px=0.11", "segment.edge_radius_px=0"}));
    EXPECT_GT(cwfid_with, cwfid_without + 0.02) << cwfid_with << " against " << cwfid_without;
    const fs::path carrot = real_data_dir() / "carrot-dev";
    const double carrot_with = mean_mask_iou(carrot, shipped_params({}));
    const double carrot_without = mean_mask_iou(carrot, shipped_params({"segment.edge_radius_px=0"}));
    EXPECT_GT(carrot_with, carrot_without) << carrot_with << " against " << carrot_without;
}

TEST(RealFrames, CarrotMaskIouStaysAboveTheFloor)
{
    // A floor against regressions while the 0.90 goal is open: plain ExG +
    // Otsu reaches 0.878 here, the shipped segmentation 0.873, and the best
    // threshold per frame on any single index 0.888 (the human masks lie
    // about a pixel down and right of the photos' edges).
    REQUIRE_REAL_SET("carrot-dev");
    const double iou = mean_mask_iou(real_data_dir() / "carrot-dev", shipped_params({}));
    EXPECT_GE(iou, 0.85);
}

namespace {

struct MaskedFrame {
    cv::Mat bgr;
    cv::Mat truth;  // 255 = vegetation
};

// A set's frames with their human masks: cwfid-train (images/, masks/ with 0
// = vegetation) or a recording directory with a mask column (carrot-dev).
std::vector<MaskedFrame> masked_frames(const std::string& set)
{
    std::vector<MaskedFrame> frames;
    const fs::path dir = real_data_dir() / set;
    if (set == "cwfid-train") {
        std::vector<fs::path> images;
        for (const auto& entry : fs::directory_iterator(dir / "images"))
            images.push_back(entry.path());
        std::sort(images.begin(), images.end());
        for (const fs::path& image : images) {
            const std::string name = image.filename().string();
            const auto cut = name.find("_image.png");
            if (cut != std::string::npos)
                frames.push_back({read(image, cv::IMREAD_COLOR),
                                  read(dir / "masks" / (name.substr(0, cut) + "_mask.png"), cv::IMREAD_GRAYSCALE) == 0});
        }
        return frames;
    }
    std::string error;
    const auto recording = io::read_recording(dir, error);
    EXPECT_TRUE(recording) << error;
    if (recording)
        for (const io::RecordingFrame& frame : recording->frames)
            frames.push_back({read(recording->resolve(frame.rgb), cv::IMREAD_COLOR),
                              read(recording->resolve(frame.mask), cv::IMREAD_GRAYSCALE) != 0});
    return frames;
}

}  // namespace

TEST(RealFrames, WindowsMostlyCoveredByLeavesKeepTheirLeaves)
{
    // A camera closer to the ground, or a patch of dense weeds, sees leaves
    // over most of its view. Windows of 160 x 160 px cut from the real
    // frames on a grid, where the human mask covers half or more: the
    // leaves' index level is then often the histogram's mode, and taken
    // for the soil's, it left those windows with an empty mask (mean IoU
    // 0.41 on CWFID's 58 such windows, 0.76 on carrot-dev's 52). A floor
    // against that; the whole frames' goal is 0.90.
    REQUIRE_REAL_SET("cwfid-train");
    REQUIRE_REAL_SET("carrot-dev");
    struct Set {
        std::string name;
        std::string gsd;
    };
    for (const Set& set : {Set{"cwfid-train", "0.11"}, Set{"carrot-dev", "0.25"}}) {
        SCOPED_TRACE(set.name);
        const vision::Params params = shipped_params({"camera.gsd_mm_per_px=" + set.gsd});
        constexpr int kWindowPx = 160;
        double sum = 0;
        int windows = 0;
        for (const MaskedFrame& frame : masked_frames(set.name)) {
            for (int y = 0; y + kWindowPx <= frame.bgr.rows; y += kWindowPx) {
                for (int x = 0; x + kWindowPx <= frame.bgr.cols; x += kWindowPx) {
                    const cv::Rect window(x, y, kWindowPx, kWindowPx);
                    const cv::Mat truth = frame.truth(window).clone();
                    if (2 * cv::countNonZero(truth) < kWindowPx * kWindowPx)
                        continue;
                    const double iou = frame_iou(frame.bgr(window).clone(), truth, params);
                    EXPECT_GT(iou, 0.5) << "window at " << x << ", " << y;
                    sum += iou;
                    ++windows;
                }
            }
        }
        ASSERT_GE(windows, 40);
        EXPECT_GE(sum / windows, 0.85) << windows << " windows";
    }
}

TEST(RealFrames, CarrotLeafColourTestCostsNothingUnderAColourCast)
{
    // Daylight changes colour (evening sun, shade, cloud), and a camera's
    // white balance is set for one of them. Under a 25 % warm or cool cast
    // (each channel scaled, as a light's colour scales it) the leaf-colour
    // test may not cost the masks more than half a point of IoU. It once
    // read G > R in absolute terms, and a warm cast then took carrot-dev
    // from 0.872 without it to 0.802 with it.
    REQUIRE_REAL_SET("carrot-dev");
    const fs::path carrot = real_data_dir() / "carrot-dev";
    const auto with_test = shipped_params({"segment.leaf_colour=true"});
    const auto without_test = shipped_params({"segment.leaf_colour=false"});
    const std::array<std::pair<const char*, cv::Scalar>, 3> lights{
        {{"neutral", cv::Scalar::all(1)}, {"warm", cv::Scalar(0.75, 1.0, 1.25)}, {"cool", cv::Scalar(1.25, 1.0, 0.8)}}};
    for (const auto& [light, gains] : lights) {
        const double with = mean_mask_iou(carrot, with_test, {.gains = gains});
        const double without = mean_mask_iou(carrot, without_test, {.gains = gains});
        EXPECT_GE(with, without - 0.005) << light << " light: " << with << " with the test, " << without << " without";
    }
}

// Exposure and gain scale a pixel's channels alike, and the chromatic index
// divides them out; the soil-relative threshold follows the noise the
// sensor adds. Two stops darker, one stop darker with 2 DN of gain noise,
// a lens's falloff to one stop at the corners, and the colour at half
// horizontal resolution of the V4L2 source's default YUYV may not cost
// either set's masks more than a point of IoU (tools/eval-robust.sh
// measured a loss of at most 0.002 on 2026-11-28).
TEST(RealFrames, MasksHoldDarkerVignettedAndUnderSensorNoise)
{
    REQUIRE_REAL_SET("cwfid-train");
    REQUIRE_REAL_SET("carrot-dev");
    const fs::path carrot = real_data_dir() / "carrot-dev";
    const auto carrot_params = shipped_params({});
    const auto cwfid_params = shipped_params({"camera.gsd_mm_per_px=0.11"});
    const double carrot_recorded = mean_mask_iou(carrot, carrot_params);
    const double cwfid_recorded = cwfid_mean_iou(cwfid_params);
    const std::array<std::pair<const char*, Light>, 4> lights{{{"two stops darker", {.exposure = 0.25}},
                                                               {"a stop darker, 2 DN noise", {.exposure = 0.5, .noise_dn = 2}},
                                                               {"a stop darker at the corners", {.corner_light = 0.5}},
                                                               {"through YUYV", {.yuyv = true}}}};
    for (const auto& [what, light] : lights) {
        const double carrot_iou = mean_mask_iou(carrot, carrot_params, light);
        const double cwfid_iou = cwfid_mean_iou(cwfid_params, light);
        EXPECT_GE(carrot_iou, carrot_recorded - 0.01) << what << ": carrot-dev " << carrot_iou << " against "
                                                      << carrot_recorded << " as recorded";
        EXPECT_GE(cwfid_iou, cwfid_recorded - 0.01) << what << ": cwfid-train " << cwfid_iou << " against "
                                                    << cwfid_recorded << " as recorded";
    }
}

// With its NIR plane the default keeps a sugar beet's stem in every frame
// when the frames are much darker and noisier (the exposure times 0.3, 2 DN
// of noise: 5 or 6 of the 6 stems over noise draws). From RGB alone it does
// not (README, Known limits).
TEST(RealFrames, BoniRobRgbAndNirKeepsAStemInEveryFrameDarkAndNoisy)
{
    REQUIRE_REAL_SET("bonirob");
    const auto truth = bonirob_truth();
    const auto params = shipped_params({"camera.gsd_mm_per_px=0.395"});
    cv::RNG rng(1);
    const Light dark{.exposure = 0.3, .noise_dn = 2};
    for (BoniRobFrame frame : bonirob_frames()) {
        frame.bgr = under(frame.bgr, dark, rng);
        frame.nir = under(frame.nir, dark, rng);
        expect_a_stem_within_5mm(frame, truth, params);
    }
}
