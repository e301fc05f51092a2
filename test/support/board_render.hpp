// Chessboard views rendered from a known camera, for the calibration tests:
// the board's corners are where cv::projectPoints puts them, the picture is
// a warp of the board plane into the distorted image (every pixel's ray
// through cv::undistortPoints onto the plane), anti-aliased, then blurred and
// given sensor noise. Independent of stemd's geometry code on purpose.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace stemd::test {

struct RenderCamera {
    cv::Matx33d k;
    std::vector<double> dist;  // OpenCV's order
    cv::Size size;
};

struct RenderBoard {
    cv::Size inner_corners;  // W x H; corner (i, j) at (i * square_mm, j * square_mm, 0)
    double square_mm = 30;
    double margin_mm = 20;   // white border around the outer squares
};

struct RenderNoise {
    double blur_sigma_px = 0.8;
    double noise_sigma = 2.0;  // grey levels
    std::uint64_t seed = 1;
};

// An 8-bit grey view of the board; rvec/tvec take board points to the
// camera (as cv::projectPoints).
cv::Mat render_board(const RenderBoard& board, const RenderCamera& camera, const cv::Vec3d& rvec,
                     const cv::Vec3d& tvec, const RenderNoise& noise);

// The inner corners' true pixels, in findChessboardCorners' row-by-row order.
std::vector<cv::Point2d> true_corners(const RenderBoard& board, const RenderCamera& camera, const cv::Vec3d& rvec,
                                      const cv::Vec3d& tvec);

// Board -> camera (rvec, tvec) that puts the board's centre at `centre_px`,
// `distance_mm` from the camera along that pixel's ray, the board turned by
// `rotation` (Rodrigues) from facing the camera squarely.
void place_board(const RenderBoard& board, const RenderCamera& camera, cv::Point2d centre_px, double distance_mm,
                 const cv::Vec3d& rotation, cv::Vec3d& rvec, cv::Vec3d& tvec);

// --- the scenes the calibration tests share ------------------------------------

// The camera every test view is taken with: 1296x966, plumb-bob distortion.
RenderCamera test_camera();

// Board views for the intrinsics: the board tilted up to ~30 degrees about
// both axes and turned in its plane, spread over the image (its corners too,
// where the distortion shows), each kViewDistanceMm from the camera.
struct ViewSpec {
    cv::Point2d centre_px;
    cv::Vec3d rotation;  // Rodrigues, from facing the camera squarely
};
const std::vector<ViewSpec>& test_views();
inline constexpr double kViewDistanceMm = 560;
RenderBoard test_board();  // 9x6, 25 mm

// A camera above the ground, camera.forward up, in the machine frame (x
// forward, y left, z up), built with cv::Rodrigues: at zero angles image
// right is -y, image down -x, the optical axis -z; then roll about x, pitch
// about y (> 0: the axis tilts forward), yaw about z.
struct GroundCamera {
    double height_mm = 650, roll_deg = 2.5, pitch_deg = 8, yaw_deg = -3;
    double axis_x_mm = 350, axis_y_mm = 40;  // where the optical axis meets the ground

    cv::Matx33d camera_to_machine() const;
    cv::Vec3d centre_mm() const;
    // A board lying on the ground, its first inner corner at (x_mm, y_mm),
    // W corners along +x, H along +y: board plane -> camera.
    void board_to_camera(double board_x_mm, double board_y_mm, cv::Vec3d& rvec, cv::Vec3d& tvec) const;
};
RenderBoard ground_test_board();  // 11x8, 25 mm
inline constexpr double kGroundBoardXMm = 250, kGroundBoardYMm = -50;

}  // namespace stemd::test
