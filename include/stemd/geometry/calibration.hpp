// Camera calibration with a chessboard: the intrinsics from several views,
// and the camera's pose above the ground from one view of a board lying flat
// at a measured machine-frame position. Pose, mount and view geometry follow
// camera_model.hpp's conventions exactly, so that what is solved here is what
// CameraModel::calibrated() rebuilds from the configuration.
//
// The board: W x H inner corners (OpenCV's pattern size: W corners per row,
// H rows), squares square_mm wide. In its own plane, corner (i, j) is at
// (i * square_mm, j * square_mm), listed row by row as findChessboardCorners
// lists them.
//
// On the ground the board lies with its W direction along machine +x
// (forward) and its H direction along +y (left); (x_mm, y_mm) is the machine
// position of its first inner corner, the one at the rear right. Which corner
// OpenCV lists first depends on the view (a chessboard looks the same turned
// half round), so the solver tries every listing of the grid and keeps the
// one that puts the camera above the ground and turned least from
// camera.forward.
//
// Pure functions: errors as text, nothing thrown.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include "stemd/geometry/camera_model.hpp"

namespace stemd::geometry {

struct Board {
    cv::Size inner_corners;  // W x H
    double square_mm = 0;
};

// Errors: fewer than 3 corners either way (OpenCV's finder needs that), a
// non-positive or non-finite square.
std::optional<std::string> check_board(const Board& board);

// The corners in the board's plane (z = 0), in the finder's order.
std::vector<cv::Point3f> board_points(const Board& board);

// The inner corners of a grey or BGR 8-bit image, refined to sub-pixel
// precision (findChessboardCorners, cornerSubPix); nullopt when the whole
// board is not found (decided by findChessboardCornersSB, which is quick
// where the classic finder can take minutes on a part of a board).
std::optional<std::vector<cv::Point2f>> find_board_corners(const cv::Mat& image, cv::Size inner_corners);

// --- intrinsics -----------------------------------------------------------

struct IntrinsicsFit {
    Intrinsics intrinsics;             // k1 k2 p1 p2 k3, the rest 0
    double rms_px = 0;                 // over all corners of all views
    std::vector<double> view_rms_px;   // per view, in the order given
};

// calibrateCamera over the views' corners (each view: board_points() order).
// Errors: a bad board, fewer than kMinViews views, a view with the wrong
// number of corners, OpenCV's failure.
inline constexpr std::size_t kMinViews = 3;
std::optional<IntrinsicsFit> calibrate_intrinsics(const std::vector<std::vector<cv::Point2f>>& views,
                                                  const Board& board, cv::Size image_size, std::string* error);

// Writes OpenCV's calibration YAML: camera_matrix, distortion_coefficients
// (5), image_width, image_height, and the fit's RMS and view count.
// read_calibration() reads it back.
bool write_calibration(const std::string& path, const IntrinsicsFit& fit, std::string* error);

// --- the pose above the ground ------------------------------------------------

struct BoardOnGround {
    Board board;
    double x_mm = 0;  // machine frame: the first (rear-right) inner corner
    double y_mm = 0;
};

// The corners' machine-frame ground positions (z = 0), in the finder's order.
std::vector<cv::Point3d> ground_board_points(const BoardOnGround& ground);

struct GroundFit {
    Pose pose;
    Mount mount;                  // forward as asked; x_mm, y_mm: the principal point's ground position
    double rms_px = 0;            // corners reprojected through the fitted CameraModel
    double ground_rms_mm = 0;     // detected corners projected to the ground vs their known positions
    double ground_max_mm = 0;
};

// solvePnP of the detected corners against their ground positions, then the
// pose in camera_model.hpp's terms. Errors: a bad board, the wrong number of
// corners, no listing of the corners that puts the camera above the ground,
// a pose whose optical axis misses the ground.
std::optional<GroundFit> solve_ground_pose(const std::vector<cv::Point2f>& corners, const BoardOnGround& ground,
                                           const Intrinsics& intrinsics, Forward forward, std::string* error);

// The pose (roll, pitch, yaw) of a camera -> machine rotation mounted as
// `forward`: the inverse of camera_to_machine_rotation() for pitch within
// (-90, 90) degrees.
Pose pose_from_rotation(const cv::Matx33d& camera_to_machine, Forward forward, double height_mm);

// --- what the view covers -------------------------------------------------------

// Ground distance covered by one pixel step at `px`, along the image's u
// (right) and v (down) directions, and their geometric mean.
struct Gsd {
    double along_u_mm_per_px = 0;
    double along_v_mm_per_px = 0;
    double mean_mm_per_px = 0;
};
// nullopt when a neighbouring pixel's ray misses the ground.
std::optional<Gsd> gsd_at(const CameraModel& camera, cv::Point2d px);

// The ground positions of the image's outer corners (the outer edges of the
// corner pixels): top left, top right, bottom right, bottom left. A corner
// whose ray misses the ground is nullopt.
std::array<std::optional<GroundPoint>, 4> ground_footprint(const CameraModel& camera, cv::Size image_size);

// The corner pixels' centres, in ground_footprint()'s order.
std::array<cv::Point2d, 4> corner_pixels(cv::Size image_size);

// --- the configuration ---------------------------------------------------------

// A config file fragment with the fitted camera: the camera section
// (model: calibrated, calibration_file, forward, the pose, the principal
// point's ground position, gsd_mm_per_px at the image centre for the
// detector's millimetre-sized constants) and the frame size the calibration
// is for (source.width_px, source.height_px). `comment` lines go on top.
std::string camera_config_fragment(const GroundFit& fit, const std::string& calibration_file, cv::Size image_size,
                                   double gsd_mm_per_px, const std::vector<std::string>& comment);

}  // namespace stemd::geometry
