// The config fragment stemd-calibrate ground writes, read back through the
// real config loader and the daemon's camera factory: the camera it builds
// puts the board's corners where they lie on the ground.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "stemd/config/config.hpp"
#include "stemd/geometry/calibration.hpp"
#include "stemd/runtime/camera_config.hpp"

namespace fs = std::filesystem;
using namespace stemd;
using namespace stemd::geometry;

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180;

cv::Matx33d rodrigues(double ax, double ay, double az)
{
    cv::Matx33d r;
    cv::Rodrigues(cv::Vec3d(ax, ay, az), r);
    return r;
}

}  // namespace

TEST(CalibrationFragment, LoadsIntoACameraThatPutsTheBoardWhereItLies)
{
    const fs::path dir = fs::temp_directory_path() / ("stemd-fragment-" + std::to_string(::getpid()));
    fs::create_directories(dir);

    IntrinsicsFit intrinsics;
    Intrinsics& k = intrinsics.intrinsics;
    k.fx = 1180;
    k.fy = 1176;
    k.cx = 655.2;
    k.cy = 470.8;
    k.dist = {-0.09, 0.05, 0.0004, -0.0007, -0.01};
    k.image_size = {1296, 966};
    intrinsics.view_rms_px = {0.1, 0.1, 0.1};
    const fs::path calibration = dir / "camera.yaml";
    std::string error;
    ASSERT_TRUE(write_calibration(calibration.string(), intrinsics, &error)) << error;

    // The true camera: forward up, rolled, pitched and turned, built apart
    // from the library.
    const double roll = -4, pitch = 12, yaw = 5, height = 720;
    const cv::Matx33d r_mc = rodrigues(0, 0, yaw * kDeg) * rodrigues(0, -pitch * kDeg, 0) *
                             rodrigues(roll * kDeg, 0, 0) * cv::Matx33d(0, -1, 0, -1, 0, 0, 0, 0, -1);
    const cv::Vec3d centre(180, 25, height);
    const BoardOnGround board{{{9, 6}, 30}, 200, -60};
    const std::vector<cv::Point3d> ground = ground_board_points(board);
    cv::Vec3d rvec;
    cv::Rodrigues(r_mc.t(), rvec);
    const cv::Vec3d tvec = -(r_mc.t() * centre);
    std::vector<cv::Point2d> pixels;
    cv::projectPoints(ground, rvec, tvec, cv::Matx33d(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1),
                      std::vector<double>(k.dist.begin(), k.dist.begin() + 5), pixels);
    const std::vector<cv::Point2f> corners(pixels.begin(), pixels.end());

    const auto fit = solve_ground_pose(corners, board, k, Forward::up, &error);
    ASSERT_TRUE(fit) << error;
    const auto fitted = CameraModel::calibrated(k, fit->pose, fit->mount);
    ASSERT_TRUE(fitted);
    const auto gsd = gsd_at(*fitted, image_centre(k.image_size));
    ASSERT_TRUE(gsd);
    const std::string fragment =
        camera_config_fragment(*fit, calibration.string(), k.image_size, gsd->mean_mm_per_px, {"a test", "fragment"});

    config::Config config;
    const auto bad = config.load_text(fragment, "fragment.yaml");
    ASSERT_FALSE(bad) << bad->to_string() << "\n" << fragment;
    const config::Settings settings = config.settings();
    EXPECT_EQ(settings.camera.model, ModelKind::calibrated);
    EXPECT_EQ(settings.camera.calibration_file, calibration.string());
    EXPECT_NEAR(settings.daemon.vision.gsd_mm_per_px, gsd->mean_mm_per_px, 1e-5);
    EXPECT_EQ(settings.daemon.frame_size, k.image_size);

    runtime::ConfigProblem problem;
    const auto camera = runtime::camera_model(settings.camera, settings.daemon.vision.gsd_mm_per_px,
                                              settings.daemon.frame_size, problem);
    ASSERT_TRUE(camera) << problem.key << ": " << problem.message;
    EXPECT_NEAR(camera->centre_mm()[2], height, 0.01);
    for (std::size_t c = 0; c < ground.size(); ++c) {
        const auto g = camera->pixel_to_ground(pixels[c]);
        ASSERT_TRUE(g);
        EXPECT_NEAR(g->x_mm, ground[c].x, 0.05) << "corner " << c;
        EXPECT_NEAR(g->y_mm, ground[c].y, 0.05) << "corner " << c;
        const auto px = camera->ground_to_pixel(ground[c].x, ground[c].y);
        ASSERT_TRUE(px);
        EXPECT_LT(cv::norm(*px - pixels[c]), 0.05) << "corner " << c;
    }
    fs::remove_all(dir);
}
