// Chessboard calibration: intrinsics from rendered views of a known camera,
// the pose above the ground from a rendered ground view, the corner listings
// a chessboard allows, GSD and footprint as hand-computed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "board_render.hpp"
#include "stemd/geometry/calibration.hpp"
#include "stemd/geometry/camera_model.hpp"

namespace fs = std::filesystem;
using namespace stemd::geometry;
using stemd::test::RenderBoard;
using stemd::test::RenderCamera;
using stemd::test::RenderNoise;

namespace {

using stemd::test::kViewDistanceMm;

RenderCamera true_camera() { return stemd::test::test_camera(); }

Intrinsics intrinsics_of(const RenderCamera& c)
{
    Intrinsics k;
    k.fx = c.k(0, 0);
    k.fy = c.k(1, 1);
    k.cx = c.k(0, 2);
    k.cy = c.k(1, 2);
    for (std::size_t i = 0; i < c.dist.size(); ++i)
        k.dist[i] = c.dist[i];
    k.image_size = c.size;
    return k;
}

// Every true corner at least this far inside the image: the views are meant
// to show the whole board.
constexpr double kInsideMarginPx = 25;

bool all_inside(const std::vector<cv::Point2d>& corners, cv::Size size)
{
    return std::all_of(corners.begin(), corners.end(), [&](const cv::Point2d& p) {
        return p.x >= kInsideMarginPx && p.y >= kInsideMarginPx && p.x <= size.width - 1 - kInsideMarginPx &&
               p.y <= size.height - 1 - kInsideMarginPx;
    });
}

const std::vector<stemd::test::ViewSpec>& kViews = stemd::test::test_views();
const RenderBoard kBoard = stemd::test::test_board();

}  // namespace

TEST(CalibrationBoard, PointsAreListedRowByRow)
{
    const auto points = board_points({{4, 3}, 10});
    ASSERT_EQ(points.size(), 12u);
    EXPECT_EQ(points[0], cv::Point3f(0, 0, 0));
    EXPECT_EQ(points[1], cv::Point3f(10, 0, 0));
    EXPECT_EQ(points[4], cv::Point3f(0, 10, 0));
    EXPECT_EQ(points[11], cv::Point3f(30, 20, 0));
    EXPECT_TRUE(check_board({{2, 5}, 10}));
    EXPECT_TRUE(check_board({{5, 5}, 0}));
    EXPECT_FALSE(check_board({{3, 3}, 1}));
}

TEST(CalibrationIntrinsics, RenderedViewsGiveTheTrueCameraWithinTargets)
{
    const RenderCamera camera = true_camera();
    std::vector<std::vector<cv::Point2f>> views;
    double corner_error_sum = 0;
    std::size_t corner_count = 0;
    for (std::size_t v = 0; v < kViews.size(); ++v) {
        cv::Vec3d rvec, tvec;
        stemd::test::place_board(kBoard, camera, kViews[v].centre_px, kViewDistanceMm, kViews[v].rotation, rvec, tvec);
        const auto truth = stemd::test::true_corners(kBoard, camera, rvec, tvec);
        ASSERT_TRUE(all_inside(truth, camera.size)) << "view " << v << " leaves the image";
        const cv::Mat image = stemd::test::render_board(kBoard, camera, rvec, tvec, {0.8, 2.0, 100 + v});
        auto corners = find_board_corners(image, kBoard.inner_corners);
        ASSERT_TRUE(corners) << "view " << v;
        // Either listing of the grid: compare with the nearer one.
        const bool reversed = cv::norm(cv::Point2d((*corners)[0]) - truth.back()) <
                              cv::norm(cv::Point2d((*corners)[0]) - truth.front());
        for (std::size_t c = 0; c < truth.size(); ++c) {
            const cv::Point2d found((*corners)[reversed ? truth.size() - 1 - c : c]);
            corner_error_sum += cv::norm(found - truth[c]);
            ++corner_count;
        }
        views.push_back(std::move(*corners));
    }
    // The finder sees the rendered corners where projectPoints put them.
    EXPECT_LT(corner_error_sum / static_cast<double>(corner_count), 0.15);

    std::string error;
    const auto fit = calibrate_intrinsics(views, {kBoard.inner_corners, kBoard.square_mm}, camera.size, &error);
    ASSERT_TRUE(fit) << error;
    const Intrinsics& k = fit->intrinsics;
    EXPECT_LT(std::abs(k.fx / camera.k(0, 0) - 1), 0.005) << k.fx;
    EXPECT_LT(std::abs(k.fy / camera.k(1, 1) - 1), 0.005) << k.fy;
    EXPECT_LT(std::abs(k.cx - camera.k(0, 2)), 2.0) << k.cx;
    EXPECT_LT(std::abs(k.cy - camera.k(1, 2)), 2.0) << k.cy;
    EXPECT_EQ(k.image_size, camera.size);
    EXPECT_LT(fit->rms_px, 0.3);
    ASSERT_EQ(fit->view_rms_px.size(), views.size());
    for (const double e : fit->view_rms_px)
        EXPECT_LT(e, 0.5);

    // The fitted camera maps pixels as the true one across the image.
    std::vector<cv::Point2d> edge = {{0, 0}, {1295, 0}, {1295, 965}, {0, 965}, {648, 0}, {0, 483}};
    std::vector<cv::Point2d> truth_n, fit_n;
    cv::undistortPoints(edge, truth_n, camera.k, camera.dist, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-9));
    cv::undistortPoints(edge, fit_n, cv::Matx33d(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1),
                        std::vector<double>(k.dist.begin(), k.dist.begin() + 5), cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-9));
    for (std::size_t i = 0; i < edge.size(); ++i)
        EXPECT_LT(cv::norm(truth_n[i] - fit_n[i]) * camera.k(0, 0), 2.0) << "pixel " << edge[i];
}

TEST(CalibrationIntrinsics, ViewsWithoutTheWholeBoardAreRejected)
{
    const RenderCamera camera = true_camera();
    // Blank soil.
    EXPECT_FALSE(find_board_corners(cv::Mat(camera.size, CV_8U, cv::Scalar(100)), kBoard.inner_corners));
    // The board half out of the image.
    cv::Vec3d rvec, tvec;
    stemd::test::place_board(kBoard, camera, {0, 483}, kViewDistanceMm, {0, 0, 0}, rvec, tvec);
    const cv::Mat cut = stemd::test::render_board(kBoard, camera, rvec, tvec, {});
    EXPECT_FALSE(find_board_corners(cut, kBoard.inner_corners));
    // The same board in full is found: the rejection is the cut, not the picture.
    stemd::test::place_board(kBoard, camera, {648, 483}, kViewDistanceMm, {0, 0, 0}, rvec, tvec);
    const cv::Mat whole = stemd::test::render_board(kBoard, camera, rvec, tvec, {});
    EXPECT_TRUE(find_board_corners(whole, kBoard.inner_corners));
    EXPECT_FALSE(find_board_corners(cv::Mat(), kBoard.inner_corners));
}

TEST(CalibrationIntrinsics, TooFewViewsOrWrongCornerCountsAreErrors)
{
    const Board board{{9, 6}, 25};
    const std::vector<cv::Point2f> corners(54, cv::Point2f(1, 1));
    std::string error;
    EXPECT_FALSE(calibrate_intrinsics({corners, corners}, board, {1296, 966}, &error));
    EXPECT_NE(error.find("at least 3 views"), std::string::npos) << error;
    std::vector<cv::Point2f> short_view(53, cv::Point2f(1, 1));
    EXPECT_FALSE(calibrate_intrinsics({corners, corners, short_view}, board, {1296, 966}, &error));
    EXPECT_NE(error.find("view 2 has 53 corners"), std::string::npos) << error;
    EXPECT_FALSE(calibrate_intrinsics({corners, corners, corners}, {{9, 6}, -1}, {1296, 966}, &error));
    // Degenerate views: OpenCV's failure comes back as text, never thrown.
    EXPECT_FALSE(calibrate_intrinsics({corners, corners, corners}, board, {1296, 966}, &error));
    EXPECT_FALSE(error.empty());
}

// --- the pose above the ground ----------------------------------------------------

namespace {

struct GroundScene {
    stemd::test::GroundCamera camera;
    Pose pose{camera.height_mm, camera.roll_deg, camera.pitch_deg, camera.yaw_deg};
    double x_mm = camera.axis_x_mm, y_mm = camera.axis_y_mm;
    BoardOnGround board{{stemd::test::ground_test_board().inner_corners, stemd::test::ground_test_board().square_mm},
                        stemd::test::kGroundBoardXMm,
                        stemd::test::kGroundBoardYMm};

    void board_to_camera(cv::Vec3d& rvec, cv::Vec3d& tvec) const
    {
        camera.board_to_camera(board.x_mm, board.y_mm, rvec, tvec);
    }
    RenderBoard render_board() const { return {board.board.inner_corners, board.board.square_mm, 15}; }
};

}  // namespace

TEST(CalibrationGround, RenderedGroundViewGivesThePoseWithinTargets)
{
    const RenderCamera camera = true_camera();
    const GroundScene scene;
    cv::Vec3d rvec, tvec;
    scene.board_to_camera(rvec, tvec);
    ASSERT_TRUE(all_inside(stemd::test::true_corners(scene.render_board(), camera, rvec, tvec), camera.size));
    const cv::Mat image = stemd::test::render_board(scene.render_board(), camera, rvec, tvec, {0.8, 2.0, 7});
    const auto corners = find_board_corners(image, scene.board.board.inner_corners);
    ASSERT_TRUE(corners);

    std::string error;
    const Intrinsics k = intrinsics_of(camera);
    const auto fit = solve_ground_pose(*corners, scene.board, k, Forward::up, &error);
    ASSERT_TRUE(fit) << error;
    EXPECT_LT(std::abs(fit->pose.height_mm / scene.pose.height_mm - 1), 0.01) << fit->pose.height_mm;
    EXPECT_LT(std::abs(fit->pose.roll_deg - scene.pose.roll_deg), 0.3) << fit->pose.roll_deg;
    EXPECT_LT(std::abs(fit->pose.pitch_deg - scene.pose.pitch_deg), 0.3) << fit->pose.pitch_deg;
    EXPECT_LT(std::abs(fit->pose.yaw_deg - scene.pose.yaw_deg), 0.3) << fit->pose.yaw_deg;
    EXPECT_EQ(fit->mount.forward, Forward::up);
    EXPECT_LT(std::hypot(fit->mount.x_mm - scene.x_mm, fit->mount.y_mm - scene.y_mm), 0.01 * scene.pose.height_mm);
    EXPECT_LT(fit->rms_px, 0.3);
    EXPECT_LT(fit->ground_max_mm, 1.0);

    // GSD at the centre and the corners as the true camera's.
    const auto truth = CameraModel::calibrated(k, scene.pose, {Forward::up, scene.x_mm, scene.y_mm});
    const auto fitted = CameraModel::calibrated(k, fit->pose, fit->mount);
    ASSERT_TRUE(truth && fitted);
    std::vector<cv::Point2d> pixels = {image_centre(camera.size)};
    for (const cv::Point2d& p : corner_pixels(camera.size))
        pixels.push_back(p);
    for (const cv::Point2d& p : pixels) {
        const auto g_true = gsd_at(*truth, p);
        const auto g_fit = gsd_at(*fitted, p);
        ASSERT_TRUE(g_true && g_fit) << p;
        EXPECT_LT(std::abs(g_fit->along_u_mm_per_px / g_true->along_u_mm_per_px - 1), 0.01) << p;
        EXPECT_LT(std::abs(g_fit->along_v_mm_per_px / g_true->along_v_mm_per_px - 1), 0.01) << p;
    }
}

TEST(CalibrationGround, EveryListingOfTheBoardGivesTheSamePose)
{
    const RenderCamera camera = true_camera();
    const Intrinsics k = intrinsics_of(camera);
    for (const cv::Size inner : {cv::Size(11, 8), cv::Size(7, 7)}) {
        GroundScene scene;
        scene.board.board.inner_corners = inner;
        cv::Vec3d rvec, tvec;
        scene.board_to_camera(rvec, tvec);
        const auto truth = stemd::test::true_corners(scene.render_board(), camera, rvec, tvec);
        const int w = inner.width, h = inner.height;
        // The finder's possible listings: as placed, turned half round, and
        // for a square board a quarter round either way.
        std::vector<std::vector<cv::Point2f>> listings(2);
        for (int j = 0; j < h; ++j)
            for (int i = 0; i < w; ++i) {
                listings[0].emplace_back(truth[static_cast<std::size_t>(j * w + i)]);
                listings[1].emplace_back(truth[static_cast<std::size_t>((h - 1 - j) * w + (w - 1 - i))]);
            }
        if (w == h) {
            listings.resize(4);
            for (int j = 0; j < h; ++j)
                for (int i = 0; i < w; ++i) {
                    listings[2].emplace_back(truth[static_cast<std::size_t>(i * w + (w - 1 - j))]);
                    listings[3].emplace_back(truth[static_cast<std::size_t>((w - 1 - i) * w + j)]);
                }
        }
        // Exact corners, but stored as floats (~1e-4 px at 1000 px): the
        // pose is exact to about 1e-5.
        constexpr double kExact = 1e-4;
        for (std::size_t l = 0; l < listings.size(); ++l) {
            std::string error;
            const auto fit = solve_ground_pose(listings[l], scene.board, k, Forward::up, &error);
            ASSERT_TRUE(fit) << error;
            EXPECT_NEAR(fit->pose.height_mm, scene.pose.height_mm, kExact) << inner << " listing " << l;
            EXPECT_NEAR(fit->pose.roll_deg, scene.pose.roll_deg, kExact) << inner << " listing " << l;
            EXPECT_NEAR(fit->pose.pitch_deg, scene.pose.pitch_deg, kExact) << inner << " listing " << l;
            EXPECT_NEAR(fit->pose.yaw_deg, scene.pose.yaw_deg, kExact) << inner << " listing " << l;
            EXPECT_NEAR(fit->mount.x_mm, scene.x_mm, kExact);
            EXPECT_NEAR(fit->mount.y_mm, scene.y_mm, kExact);
            EXPECT_LT(fit->ground_max_mm, kExact);
        }
    }
}

TEST(CalibrationGround, AWrongCornerCountIsAnError)
{
    const RenderCamera camera = true_camera();
    const Intrinsics k = intrinsics_of(camera);
    GroundScene scene;
    cv::Vec3d rvec, tvec;
    scene.board_to_camera(rvec, tvec);
    const auto truth = stemd::test::true_corners(scene.render_board(), camera, rvec, tvec);
    std::string error;
    std::vector<cv::Point2f> corners(truth.begin(), truth.end());
    corners.pop_back();
    EXPECT_FALSE(solve_ground_pose(corners, scene.board, k, Forward::up, &error));
    EXPECT_NE(error.find("87 corners"), std::string::npos) << error;
}

TEST(CalibrationGround, PoseFromRotationInvertsTheCameraModelsRotation)
{
    for (const Forward f : {Forward::up, Forward::down, Forward::left, Forward::right})
        for (const Pose& pose : {Pose{500, 0, 0, 0}, Pose{420, 12.5, -7.25, 31}, Pose{800, -30, 25, -170},
                                 Pose{300, 44, -44, 179}}) {
            const Pose back = pose_from_rotation(camera_to_machine_rotation(f, pose), f, pose.height_mm);
            EXPECT_NEAR(back.roll_deg, pose.roll_deg, 1e-9) << to_string(f);
            EXPECT_NEAR(back.pitch_deg, pose.pitch_deg, 1e-9) << to_string(f);
            EXPECT_NEAR(back.yaw_deg, pose.yaw_deg, 1e-9) << to_string(f);
            EXPECT_EQ(back.height_mm, pose.height_mm);
        }
}

TEST(CalibrationGround, GsdAndFootprintOfANadirPinholeAsHandComputed)
{
    // 1000 px focal length at 500 mm: 0.5 mm per pixel everywhere.
    Intrinsics k;
    k.fx = k.fy = 1000;
    k.cx = 99.5;
    k.cy = 49.5;
    k.image_size = {200, 100};
    const auto camera = CameraModel::calibrated(k, {500, 0, 0, 0}, {Forward::up, 300, 20});
    ASSERT_TRUE(camera);
    for (const cv::Point2d p : {cv::Point2d(99.5, 49.5), cv::Point2d(0, 0), cv::Point2d(199, 99)}) {
        const auto g = gsd_at(*camera, p);
        ASSERT_TRUE(g);
        EXPECT_NEAR(g->along_u_mm_per_px, 0.5, 1e-9);
        EXPECT_NEAR(g->along_v_mm_per_px, 0.5, 1e-9);
        EXPECT_NEAR(g->mean_mm_per_px, 0.5, 1e-9);
    }
    // Forward up: the image's top edge is 25 mm ahead of the principal point
    // (50 px), its left edge 50 mm to the left (100 px).
    const auto f = ground_footprint(*camera, k.image_size);
    const double expected[4][2] = {{325, 70}, {325, -30}, {275, -30}, {275, 70}};
    for (std::size_t c = 0; c < 4; ++c) {
        ASSERT_TRUE(f[c]);
        EXPECT_NEAR(f[c]->x_mm, expected[c][0], 1e-9) << c;
        EXPECT_NEAR(f[c]->y_mm, expected[c][1], 1e-9) << c;
    }
    // Pitched 44 degrees forward with a wide lens (59 degrees from the axis
    // to the top edge), the top edge looks above the horizon.
    k.fx = k.fy = 30;
    const auto wide = CameraModel::calibrated(k, {500, 0, 44, 0}, {Forward::up, 300, 20});
    ASSERT_TRUE(wide);
    const auto fw = ground_footprint(*wide, k.image_size);
    EXPECT_FALSE(fw[0]);
    EXPECT_FALSE(fw[1]);
    EXPECT_TRUE(fw[2]);
    EXPECT_TRUE(fw[3]);
}
