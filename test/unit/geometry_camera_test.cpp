// Camera models: nadir mapping per camera.forward, the calibrated pinhole
// against OpenCV's own projectPoints/undistortPoints, round trips, reading
// OpenCV's calibration YAML, field positions.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sys/stat.h>
#include <unistd.h>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "stemd/geometry/camera_model.hpp"
#include "stemd/geometry/field.hpp"
#include "temp_dir_test.hpp"

namespace fs = std::filesystem;
using namespace stemd::geometry;

namespace {

constexpr double kPi = 3.14159265358979323846;

CameraModel nadir_model(Forward forward, double gsd = 0.5, cv::Point2d principal = {10, 20}, double x_mm = 100,
                        double y_mm = -30)
{
    NadirParams p;
    p.gsd_mm_per_px = gsd;
    p.principal_px = principal;
    p.mount = {forward, x_mm, y_mm};
    std::string error;
    const auto m = CameraModel::nadir(p, &error);
    EXPECT_TRUE(m) << error;
    return m.value_or(CameraModel{});
}

Intrinsics test_intrinsics(int n_dist)
{
    Intrinsics k;
    k.fx = 1000;
    k.fy = 1005;
    k.cx = 640.3;
    k.cy = 480.7;
    k.image_size = {1280, 960};
    const double d[12] = {-0.12, 0.05, 0.001, -0.0015, -0.01, 0.02, -0.005, 0.001, 0.0005, -0.0002, 0.0003, 0.0001};
    for (int i = 0; i < n_dist; ++i)
        k.dist[static_cast<std::size_t>(i)] = d[i];
    return k;
}

CameraModel calibrated_model(const Intrinsics& k, const Pose& pose, const Mount& mount)
{
    std::string error;
    const auto m = CameraModel::calibrated(k, pose, mount, &error);
    EXPECT_TRUE(m) << error;
    return m.value_or(CameraModel{});
}

// The pose built independently of the library, with cv::Rodrigues.
cv::Matx33d rodrigues(double ax, double ay, double az)
{
    cv::Matx33d r;
    cv::Rodrigues(cv::Vec3d(ax, ay, az), r);
    return r;
}

struct OpenCvPose {
    cv::Vec3d rvec, tvec;  // machine -> camera, as projectPoints wants
};

OpenCvPose opencv_pose(const Pose& pose, const Mount& mount)
{
    // Looking down, image up = forward (camera.forward: up).
    EXPECT_EQ(mount.forward, Forward::up);
    const cv::Matx33d base(0, -1, 0, -1, 0, 0, 0, 0, -1);
    const double d = kPi / 180;
    const cv::Matx33d r_mc = rodrigues(0, 0, pose.yaw_deg * d) * rodrigues(0, -pose.pitch_deg * d, 0) *
                             rodrigues(pose.roll_deg * d, 0, 0) * base;
    const cv::Vec3d axis(r_mc(0, 2), r_mc(1, 2), r_mc(2, 2));
    const double t = pose.height_mm / -axis[2];
    const cv::Vec3d centre(mount.x_mm - t * axis[0], mount.y_mm - t * axis[1], pose.height_mm);
    const cv::Matx33d r_cm = r_mc.t();
    OpenCvPose out;
    cv::Rodrigues(r_cm, out.rvec);
    out.tvec = -(r_cm * centre);
    return out;
}

std::vector<double> dist_vector(const Intrinsics& k, int n)
{
    return std::vector<double>(k.dist.begin(), k.dist.begin() + n);
}

cv::Matx33d camera_matrix(const Intrinsics& k)
{
    return {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1};
}

}  // namespace

// --- nadir ------------------------------------------------------------------

TEST(NadirCamera, MapsEachForwardDirectionAsHandComputed)
{
    // gsd 0.5 mm/px, principal point (10, 20), camera at (100, -30) mm.
    // Pixel (14, 17): 4 px right of and 3 px above the principal point.
    struct Case {
        Forward forward;
        double forward_mm, lateral_mm;
    };
    const Case cases[] = {
        {Forward::up, 1.5, -2.0},     // up is forward, right is the machine's right (-y)
        {Forward::down, -1.5, 2.0},   // down is forward, right is left (+y)
        {Forward::right, 2.0, 1.5},   // right is forward, up is left
        {Forward::left, -2.0, -1.5},  // left is forward, up is right
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(std::string(to_string(c.forward)));
        const CameraModel m = nadir_model(c.forward);
        const auto g = m.pixel_to_ground({14, 17});
        ASSERT_TRUE(g);
        EXPECT_DOUBLE_EQ(g->forward_mm, c.forward_mm);
        EXPECT_DOUBLE_EQ(g->lateral_mm, c.lateral_mm);
        EXPECT_DOUBLE_EQ(g->x_mm, 100 + c.forward_mm);
        EXPECT_DOUBLE_EQ(g->y_mm, -30 + c.lateral_mm);
        const auto at_principal = m.pixel_to_ground({10, 20});
        ASSERT_TRUE(at_principal);
        EXPECT_EQ(at_principal->forward_mm, 0);
        EXPECT_EQ(at_principal->lateral_mm, 0);
        EXPECT_EQ(at_principal->x_mm, 100);
        EXPECT_EQ(at_principal->y_mm, -30);
    }
}

TEST(NadirCamera, WithForwardUpPlantsMoveDownTheImageAsTheMachineAdvances)
{
    const CameraModel m = nadir_model(Forward::up, 0.33, image_centre({1296, 966}), 0, 0);
    // A plant 20 mm ahead of the camera; the machine advances 10 mm, so the
    // plant is 10 mm ahead.
    const auto before = m.ground_to_pixel(20, 5);
    const auto after = m.ground_to_pixel(10, 5);
    ASSERT_TRUE(before && after);
    EXPECT_GT(after->y, before->y);
    EXPECT_NEAR(after->y - before->y, 10 / 0.33, 1e-9);
    EXPECT_DOUBLE_EQ(after->x, before->x);
    EXPECT_LT(before->x, image_centre({1296, 966}).x);  // left of the machine is left in the image
}

TEST(NadirCamera, ImageCentreHasPixelCentresAtIntegers)
{
    EXPECT_EQ(image_centre({1296, 966}), cv::Point2d(647.5, 482.5));
    EXPECT_EQ(image_centre({5, 3}), cv::Point2d(2, 1));
}

TEST(NadirCamera, RoundTripsEveryForward)
{
    for (const Forward f : {Forward::up, Forward::down, Forward::left, Forward::right}) {
        const CameraModel m = nadir_model(f, 0.33, {647.5, 482.5}, 812.5, -12.25);
        for (double u = -3.25; u < 1300; u += 97.5)
            for (double v = 0.5; v < 970; v += 61.75) {
                const auto g = m.pixel_to_ground({u, v});
                ASSERT_TRUE(g);
                const auto px = m.ground_to_pixel(g->x_mm, g->y_mm);
                ASSERT_TRUE(px);
                EXPECT_NEAR(px->x, u, 1e-9);
                EXPECT_NEAR(px->y, v, 1e-9);
            }
    }
}

TEST(NadirCamera, RejectsANonPositiveGsd)
{
    NadirParams p;
    p.gsd_mm_per_px = 0;
    std::string error;
    EXPECT_FALSE(CameraModel::nadir(p, &error));
    EXPECT_NE(error.find("gsd_mm_per_px"), std::string::npos) << error;
}

TEST(CameraModelNames, ParseAndPrint)
{
    for (const Forward f : {Forward::up, Forward::down, Forward::left, Forward::right})
        EXPECT_EQ(parse_forward(to_string(f)), f);
    EXPECT_EQ(parse_model_kind("nadir"), ModelKind::nadir);
    EXPECT_EQ(parse_model_kind("calibrated"), ModelKind::calibrated);
    EXPECT_FALSE(parse_forward("forward"));
    EXPECT_FALSE(parse_model_kind(""));
}

// --- calibrated -------------------------------------------------------------

TEST(CalibratedCamera, TiltedPosesAsHandComputed)
{
    Intrinsics k = test_intrinsics(0);
    // Pitch 30 deg forward, 500 mm up, principal point's ground position at
    // the machine origin: the optical centre is 500 tan 30 behind it, and the
    // ground straight below the camera is 30 deg below the axis.
    {
        const CameraModel m = calibrated_model(k, {500, 0, 30, 0}, {Forward::up, 0, 0});
        const double back = 500 * std::tan(30 * kPi / 180);
        EXPECT_NEAR(m.centre_mm()[0], -back, 1e-9);
        EXPECT_NEAR(m.centre_mm()[1], 0, 1e-9);
        const auto below = m.ground_to_pixel(-back, 0);
        ASSERT_TRUE(below);
        EXPECT_NEAR(below->x, k.cx, 1e-9);
        EXPECT_NEAR(below->y, k.cy + k.fy * std::tan(30 * kPi / 180), 1e-9);
        const auto g = m.pixel_to_ground({k.cx, k.cy});
        ASSERT_TRUE(g);
        EXPECT_NEAR(g->x_mm, 0, 1e-9);
        EXPECT_NEAR(g->y_mm, 0, 1e-9);
        // Further ahead is higher in the image, and stretched.
        const auto ahead = m.ground_to_pixel(100, 0);
        const auto behind = m.ground_to_pixel(-100, 0);
        ASSERT_TRUE(ahead && behind);
        EXPECT_LT(ahead->y, k.cy);
        EXPECT_GT(behind->y, k.cy);
        EXPECT_LT(k.cy - ahead->y, behind->y - k.cy);
    }
    // Roll 30 deg to the left: the ground below the camera is right of the axis.
    {
        const CameraModel m = calibrated_model(k, {500, 30, 0, 0}, {Forward::up, 0, 0});
        const double side = 500 * std::tan(30 * kPi / 180);
        EXPECT_NEAR(m.centre_mm()[1], -side, 1e-9);
        const auto below = m.ground_to_pixel(0, -side);
        ASSERT_TRUE(below);
        EXPECT_NEAR(below->x, k.cx + k.fx * std::tan(30 * kPi / 180), 1e-9);
        EXPECT_NEAR(below->y, k.cy, 1e-9);
    }
    // Yaw 90 deg (counter-clockwise from above): image up now points left (+y).
    {
        const CameraModel m = calibrated_model(k, {500, 0, 0, 90}, {Forward::up, 0, 0});
        const auto left = m.ground_to_pixel(0, 100);
        ASSERT_TRUE(left);
        EXPECT_NEAR(left->x, k.cx, 1e-9);
        EXPECT_NEAR(left->y, k.cy - k.fy * 100 / 500, 1e-9);
    }
    // Looking straight down without distortion, it is a nadir camera with
    // gsd = height / f, whatever camera.forward says.
    for (const Forward f : {Forward::up, Forward::down, Forward::left, Forward::right}) {
        Intrinsics square = k;
        square.fy = square.fx;
        const CameraModel cal = calibrated_model(square, {500, 0, 0, 0}, {f, 40, -7});
        const CameraModel nad = nadir_model(f, 500 / square.fx, {square.cx, square.cy}, 40, -7);
        for (const cv::Point2d px : {cv::Point2d(0, 0), cv::Point2d(1279, 959), cv::Point2d(100.5, 900.25)}) {
            const auto a = cal.pixel_to_ground(px);
            const auto b = nad.pixel_to_ground(px);
            ASSERT_TRUE(a && b);
            EXPECT_NEAR(a->x_mm, b->x_mm, 1e-9);
            EXPECT_NEAR(a->y_mm, b->y_mm, 1e-9);
        }
    }
}

TEST(CalibratedCamera, MatchesOpenCvProjectPointsWithDistortionAndTilt)
{
    const Mount mount{Forward::up, 300, -50};
    const Pose poses[] = {{600, 0, 0, 0}, {600, 5, 20, 10}, {450, -12, 35, -150}, {800, 40, -10, 90}};
    for (const int n_dist : {4, 5, 8, 12}) {
        const Intrinsics k = test_intrinsics(n_dist);
        const std::vector<double> dist = dist_vector(k, n_dist);
        for (const Pose& pose : poses) {
            SCOPED_TRACE(::testing::Message() << "dist " << n_dist << " roll " << pose.roll_deg << " pitch "
                                              << pose.pitch_deg << " yaw " << pose.yaw_deg);
            const CameraModel m = calibrated_model(k, pose, mount);
            const OpenCvPose cvpose = opencv_pose(pose, mount);
            std::vector<cv::Point3d> ground;
            for (double x = -400; x <= 400; x += 20)
                for (double y = -400; y <= 400; y += 20)
                    ground.emplace_back(mount.x_mm + x, mount.y_mm + y, 0);
            std::vector<cv::Point2d> pixels;
            cv::projectPoints(ground, cvpose.rvec, cvpose.tvec, camera_matrix(k), dist, pixels);
            int inside = 0;
            for (std::size_t i = 0; i < ground.size(); ++i) {
                const cv::Point2d px = pixels[i];
                // Only what the camera sees (and in front of it).
                if (px.x < 0 || px.y < 0 || px.x > k.image_size.width - 1 || px.y > k.image_size.height - 1)
                    continue;
                const auto ours = m.ground_to_pixel(ground[i].x, ground[i].y);
                if (!ours)
                    continue;  // behind the camera: projectPoints folds it in
                ++inside;
                EXPECT_NEAR(ours->x, px.x, 1e-6);
                EXPECT_NEAR(ours->y, px.y, 1e-6);
                const auto g = m.pixel_to_ground(px);
                ASSERT_TRUE(g) << px;
                EXPECT_NEAR(g->x_mm, ground[i].x, 0.1) << px;
                EXPECT_NEAR(g->y_mm, ground[i].y, 0.1) << px;
                EXPECT_NEAR(g->forward_mm, ground[i].x - mount.x_mm, 0.1);
                EXPECT_NEAR(g->lateral_mm, ground[i].y - mount.y_mm, 0.1);
            }
            EXPECT_GT(inside, 100);
        }
    }
}

TEST(CalibratedCamera, UndistortionMatchesOpenCv)
{
    for (const int n_dist : {5, 8, 12}) {
        const Intrinsics k = test_intrinsics(n_dist);
        const CameraModel m = calibrated_model(k, {500, 0, 0, 0}, {});
        std::vector<cv::Point2d> pixels;
        for (double u = 0; u < 1280; u += 79.5)
            for (double v = 0; v < 960; v += 59.25)
                pixels.emplace_back(u, v);
        std::vector<cv::Point2d> theirs;
        cv::undistortPoints(pixels, theirs, camera_matrix(k), dist_vector(k, n_dist), cv::noArray(), cv::noArray(),
                            cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-10));
        for (std::size_t i = 0; i < pixels.size(); ++i) {
            const auto ours = m.undistort_normalised(pixels[i]);
            ASSERT_TRUE(ours) << pixels[i];
            EXPECT_NEAR(ours->x, theirs[i].x, 1e-8) << pixels[i];
            EXPECT_NEAR(ours->y, theirs[i].y, 1e-8) << pixels[i];
        }
    }
}

TEST(CalibratedCamera, RoundTripsPixelsAcrossTheImage)
{
    const Intrinsics k = test_intrinsics(8);
    const CameraModel m = calibrated_model(k, {650, -8, 25, 30}, {Forward::right, 1200, 350});
    for (double u = 0; u < 1280; u += 63.5)
        for (double v = 0; v < 960; v += 47.75) {
            const auto g = m.pixel_to_ground({u, v});
            ASSERT_TRUE(g) << u << "," << v;
            const auto px = m.ground_to_pixel(g->x_mm, g->y_mm);
            ASSERT_TRUE(px);
            EXPECT_NEAR(px->x, u, 1e-6);
            EXPECT_NEAR(px->y, v, 1e-6);
        }
}

TEST(CalibratedCamera, RaysAboveTheHorizonMissTheGround)
{
    Intrinsics k = test_intrinsics(0);
    // Pitched 45 deg forward with a 90 deg+ field of view upwards: the top
    // rows look above the horizon.
    k.fy = 300;
    const CameraModel m = calibrated_model(k, {500, 0, 45, 0}, {});
    EXPECT_FALSE(m.pixel_to_ground({k.cx, 0}));
    EXPECT_TRUE(m.pixel_to_ground({k.cx, 959}));
    EXPECT_FALSE(m.ground_to_pixel(-5000, 0));  // behind the camera
}

TEST(CalibratedCamera, RejectsBadIntrinsicsAndHeights)
{
    std::string error;
    Intrinsics k = test_intrinsics(5);
    EXPECT_FALSE(CameraModel::calibrated(k, {0, 0, 0, 0}, {}, &error));
    EXPECT_NE(error.find("height_mm"), std::string::npos) << error;
    k.fx = 0;
    EXPECT_FALSE(CameraModel::calibrated(k, {500, 0, 0, 0}, {}, &error));
    EXPECT_NE(error.find("focal"), std::string::npos) << error;
    k = test_intrinsics(5);
    EXPECT_FALSE(CameraModel::calibrated(k, {500, 0, 90, 0}, {}, &error));
    EXPECT_NE(error.find("does not meet the ground"), std::string::npos) << error;
}

// --- calibration files ------------------------------------------------------

// Read back exactly what test_intrinsics(n_dist) wrote, at 1280x960.
void expect_written_intrinsics(const Intrinsics& k, int n_dist)
{
    const Intrinsics expected = test_intrinsics(n_dist);
    EXPECT_EQ(k.fx, expected.fx);
    EXPECT_EQ(k.fy, expected.fy);
    EXPECT_EQ(k.cx, expected.cx);
    EXPECT_EQ(k.cy, expected.cy);
    EXPECT_EQ(k.dist, expected.dist);
    EXPECT_EQ(k.image_size, cv::Size(1280, 960));
}

class CalibrationFileTest : public stemd::test::TempDirTest {
protected:

    fs::path write_calibration(const std::string& name, bool with_matrix, bool with_dist, int n_dist = 5)
    {
        const fs::path path = dir_ / name;
        cv::FileStorage out(path.string(), cv::FileStorage::WRITE);
        out << "image_width" << 1280 << "image_height" << 960;
        const Intrinsics k = test_intrinsics(n_dist);
        if (with_matrix)
            out << "camera_matrix" << cv::Mat(camera_matrix(k));
        if (with_dist)
            out << "distortion_coefficients" << cv::Mat(dist_vector(k, n_dist), true);
        out << "avg_reprojection_error" << 0.21;
        return path;
    }
};

TEST_F(CalibrationFileTest, ReadsWhatOpenCvWrites)
{
    for (const int n : {4, 5, 8, 12}) {
        const fs::path path = write_calibration("camera" + std::to_string(n) + ".yaml", true, true, n);
        std::string error;
        const auto k = read_calibration(path.string(), &error);
        ASSERT_TRUE(k) << error;
        expect_written_intrinsics(*k, n);
    }
}

TEST_F(CalibrationFileTest, MissingNodesAndBadFilesAreClearErrors)
{
    std::string error;
    const fs::path no_dist = write_calibration("no_dist.yaml", true, false);
    EXPECT_FALSE(read_calibration(no_dist.string(), &error));
    EXPECT_EQ(error, no_dist.string() + ": missing node 'distortion_coefficients'");

    const fs::path no_matrix = write_calibration("no_matrix.yaml", false, true);
    EXPECT_FALSE(read_calibration(no_matrix.string(), &error));
    EXPECT_EQ(error, no_matrix.string() + ": missing node 'camera_matrix'");

    const fs::path tilted = write_calibration("tilted.yaml", true, true, 4);
    {
        cv::FileStorage out(tilted.string(), cv::FileStorage::WRITE);
        out << "image_width" << 1280 << "image_height" << 960 << "camera_matrix"
            << cv::Mat(camera_matrix(test_intrinsics(0))) << "distortion_coefficients" << cv::Mat::zeros(14, 1, CV_64F);
    }
    EXPECT_FALSE(read_calibration(tilted.string(), &error));
    EXPECT_NE(error.find("tilted-sensor"), std::string::npos) << error;

    const fs::path missing = dir_ / "does_not_exist.yaml";
    EXPECT_FALSE(read_calibration(missing.string(), &error));
    EXPECT_EQ(error.rfind(missing.string() + ": ", 0), 0u) << error;

    const fs::path garbage = dir_ / "garbage.yaml";
    std::ofstream(garbage) << "%YAML:1.0\ncamera_matrix: [1, 2\n  : : {\n";
    EXPECT_FALSE(read_calibration(garbage.string(), &error));  // never throws
    EXPECT_EQ(error.rfind(garbage.string() + ": ", 0), 0u) << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;

    const fs::path no_size = dir_ / "no_size.yaml";
    {
        cv::FileStorage out(no_size.string(), cv::FileStorage::WRITE);
        out << "camera_matrix" << cv::Mat(camera_matrix(test_intrinsics(0)));
    }
    EXPECT_FALSE(read_calibration(no_size.string(), &error));
    EXPECT_EQ(error, no_size.string() + ": missing or non-integer node 'image_width'");

    // A FIFO no one writes (a blocking open would hang here until ctest's
    // timeout), a device that never ends, a directory: refused at once.
    const fs::path fifo = dir_ / "fifo.yaml";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    for (const fs::path& path : {fifo, fs::path("/dev/zero"), dir_}) {
        EXPECT_FALSE(read_calibration(path.string(), &error));
        EXPECT_EQ(error, path.string() + ": cannot read the calibration file: not a regular file");
    }
}

TEST_F(CalibrationFileTest, ReadsRosCameraInfo)
{
    const fs::path path = dir_ / "camera_info.yaml";
    std::ofstream(path) << "image_width: 1280\n"
                           "image_height: 960\n"
                           "camera_name: test\n"
                           "camera_matrix:\n"
                           "  rows: 3\n"
                           "  cols: 3\n"
                           "  data: [1000, 0, 640.3, 0, 1005, 480.7, 0, 0, 1]\n"
                           "distortion_model: rational_polynomial\n"
                           "distortion_coefficients:\n"
                           "  rows: 1\n"
                           "  cols: 8\n"
                           "  data: [-0.12, 0.05, 0.001, -0.0015, -0.01, 0.02, -0.005, 0.001]\n"
                           "rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}\n"
                           "projection_matrix: {rows: 3, cols: 4, data: [1000, 0, 640.3, 0, 0, 1005, 480.7, 0, 0, 0, "
                           "1, 0]}\n";
    std::string error;
    const auto k = read_calibration(path.string(), &error);
    ASSERT_TRUE(k) << error;
    expect_written_intrinsics(*k, 8);

    // ROS leaves the list empty for a camera without distortion.
    const fs::path empty = dir_ / "no_distortion.yaml";
    std::ofstream(empty) << "image_width: 640\nimage_height: 480\n"
                            "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n"
                            "distortion_coefficients: {rows: 1, cols: 0, data: []}\n";
    const auto none = read_calibration(empty.string(), &error);
    ASSERT_TRUE(none) << error;
    EXPECT_EQ(none->dist, (std::array<double, 12>{}));
}

TEST_F(CalibrationFileTest, MalformedRosCameraInfoNamesFileAndKey)
{
    const std::string size = "image_width: 640\nimage_height: 480\n";
    const std::string matrix = "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n";
    const std::string dist = "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n";
    struct Case {
        std::string text;
        std::string message;
    };
    const Case cases[] = {
        {size + dist, "missing node 'camera_matrix'"},
        {size + matrix, "missing node 'distortion_coefficients'"},
        {"image_height: 480\n" + matrix + dist, "missing node 'image_width'"},
        {"image_width: wide\nimage_height: 480\n" + matrix + dist, "node 'image_width' is not an integer"},
        {size + "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0]}\n" + dist,
         "node 'camera_matrix': 'data' has 8 values, rows x cols is 9"},
        {size + "camera_matrix: {rows: 2, cols: 2, data: [500, 0, 0, 500]}\n" + dist,
         "node 'camera_matrix' is not a 3x3 matrix"},
        {size + "camera_matrix: {rows: 3, cols: 3, data: [500, 0, x, 0, 500, 240, 0, 0, 1]}\n" + dist,
         "node 'camera_matrix': 'data' value 2 is not a finite number"},
        {size + "camera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n" + dist,
         "node 'camera_matrix' is not a map with rows, cols and data"},
        {size + matrix + "distortion_model: equidistant\n" + dist,
         "node 'distortion_model': 'equidistant' is not supported (plumb_bob or rational_polynomial, OpenCV's "
         "model)"},
        {size + matrix + "distortion_coefficients: {rows: 1, cols: 3, data: [0, 0, 0]}\n",
         "node 'distortion_coefficients' must hold 0, 4, 5, 8 or 12 values"},
        {size + "camera_matrix: {rows: 3, cols: 3, data: [-500, 0, 320, 0, 500, 240, 0, 0, 1]}\n" + dist,
         "node 'camera_matrix' has a non-positive focal length"},
        {size + matrix + dist + "image_width: [\n", "line 6: invalid YAML: "},
        {"- a list\n", "not a map of calibration nodes (camera_matrix, distortion_coefficients, image_width, "
                       "image_height)"},
    };
    int n = 0;
    for (const Case& c : cases) {
        const fs::path path = dir_ / ("bad" + std::to_string(n++) + ".yaml");
        std::ofstream(path) << c.text;
        std::string error;
        EXPECT_FALSE(read_calibration(path.string(), &error)) << c.text;
        EXPECT_EQ(error.rfind(path.string() + ": " + c.message, 0), 0u) << error;
        EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    }
}

// The camera_info shipped with the BoniRob data set (../shared/data or
// STEMD_REAL_DATA).
TEST(RealCalibrationFile, BonirobCameraInfoLoads)
{
    const char* env = std::getenv("STEMD_REAL_DATA");
    const fs::path data = env ? fs::path(env) : fs::path(STEMD_SOURCE_DIR) / ".." / "shared" / "data";
    const fs::path path = data / "bonirob" / "jai_camera_rgb.yaml";
    if (!fs::exists(path))
        GTEST_SKIP() << path.string() << " is absent (set STEMD_REAL_DATA to the folder holding bonirob/)";
    std::string error;
    const auto k = read_calibration(path.string(), &error);
    ASSERT_TRUE(k) << error;
    EXPECT_EQ(k->image_size, cv::Size(1296, 966));
    EXPECT_DOUBLE_EQ(k->fx, 2150.03686);
    EXPECT_DOUBLE_EQ(k->fy, 2150.03686);
    EXPECT_DOUBLE_EQ(k->cx, 649.2291);
    EXPECT_DOUBLE_EQ(k->cy, 480.680634);
    EXPECT_EQ(k->dist, (std::array<double, 12>{}));
    // The daemon's default frame size is this camera's.
    EXPECT_TRUE(CameraModel::calibrated(*k, {800, 0, 0, 0}, {}, &error)) << error;
}

// --- field positions ----------------------------------------------------------

TEST(FieldPosition, AddsTheForwardOffsetToTheOdometerAndKeepsMachineY)
{
    const CameraModel m = nadir_model(Forward::up);  // 0.5 mm/px, principal (10, 20), at (100, -30)
    const auto f = field_position(m, {14, 17}, 1000);
    ASSERT_TRUE(f);
    EXPECT_DOUBLE_EQ(f->s_mm, 1001.5);
    EXPECT_DOUBLE_EQ(f->y_mm, -32.0);
    // The same stem seen in a later frame, after 10 mm of travel, 20 px lower:
    // the same field position.
    const auto later = field_position(m, {14, 37}, 1010);
    ASSERT_TRUE(later);
    EXPECT_DOUBLE_EQ(later->s_mm, f->s_mm);
    EXPECT_DOUBLE_EQ(later->y_mm, f->y_mm);
}

TEST(FieldPosition, MissesReportNothing)
{
    Intrinsics k = test_intrinsics(0);
    k.fy = 300;
    const CameraModel m = calibrated_model(k, {500, 0, 45, 0}, {});
    EXPECT_FALSE(field_position(m, {640, 0}, 0));
}
