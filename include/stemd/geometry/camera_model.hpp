// Camera models: image pixel <-> point on the ground, in the machine frame.
//
// Conventions (the whole geometry room uses them):
//  - Machine frame: x forward (the direction of travel), y to the left, z up,
//    millimetres; the ground is the plane z = 0.
//  - Image: u to the right, v down, pixel centres at integer coordinates
//    (as vision::Plant::stem); OpenCV's camera frame: x right, y down, z
//    along the optical axis.
//  - camera.forward: which image direction points in the direction of travel.
//    up (the default): plants move down the image as the machine advances.
//  - The camera's reference point is the principal point's ground position:
//    where the optical axis meets the ground (for a nadir camera, the point
//    straight below it). camera.x_mm / camera.y_mm place it in the machine
//    frame. A GroundPoint carries both its offset from that point
//    (forward_mm, lateral_mm: along machine x and y) and its machine-frame
//    position (x_mm = camera.x_mm + forward_mm, y_mm = camera.y_mm + lateral_mm).
//  - Calibrated pose: the camera at height_mm above the ground. At zero
//    angles it looks straight down, mounted as camera.forward says. Then
//    roll_deg turns it about machine x (> 0: the optical axis tilts to the
//    left, +y), then pitch_deg about machine y (> 0: the axis tilts forward,
//    +x), then yaw_deg about machine z (> 0: counter-clockwise seen from
//    above, from +x towards +y). Camera to machine: Rz(yaw) Ry(-pitch)
//    Rx(roll) R_forward.
//  - Distortion: OpenCV's model with 4, 5, 8 or 12 coefficients
//    (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4]]]); the tilted-sensor model (14)
//    is not supported. Skew in the camera matrix is ignored, as
//    cv::projectPoints does.
//
// Every mapping is a pure function of a small value type: no allocation,
// no exceptions.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <opencv2/core/matx.hpp>
#include <opencv2/core/types.hpp>

#include "stemd/base/enum_names.hpp"

namespace stemd::geometry {

// Which image direction points in the direction of travel.
enum class Forward : std::uint8_t { up, down, left, right };
enum class ModelKind : std::uint8_t { nadir, calibrated };
inline constexpr base::EnumName<Forward> kForwardNames[]{
    {Forward::up, "up"}, {Forward::down, "down"}, {Forward::left, "left"}, {Forward::right, "right"}};
inline constexpr base::EnumName<ModelKind> kModelKindNames[]{{ModelKind::nadir, "nadir"},
                                                             {ModelKind::calibrated, "calibrated"}};

std::string_view to_string(Forward v);
std::string_view to_string(ModelKind v);
std::optional<Forward> parse_forward(std::string_view s);
std::optional<ModelKind> parse_model_kind(std::string_view s);

// The principal point of a camera with no calibration: the image centre,
// ((width - 1) / 2, (height - 1) / 2) with pixel centres at integers.
cv::Point2d image_centre(cv::Size image_size);

// Where the camera is mounted on the machine (both models).
struct Mount {
    Forward forward = Forward::up;
    double x_mm = 0;  // principal point's ground position, machine frame
    double y_mm = 0;
};

// A camera looking straight down at a known ground sampling distance.
struct NadirParams {
    double gsd_mm_per_px = 0.33;
    cv::Point2d principal_px{0, 0};  // usually image_centre(size)
    Mount mount;
};

// Intrinsics as OpenCV's calibration writes them.
struct Intrinsics {
    double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
    // k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4; absent ones are 0.
    std::array<double, 12> dist{};
    cv::Size image_size;
};

// The calibrated camera's pose above the ground plane.
struct Pose {
    double height_mm = 500;  // optical centre above the ground
    double roll_deg = 0;
    double pitch_deg = 0;
    double yaw_deg = 0;
};

// A point on the ground.
struct GroundPoint {
    double forward_mm = 0;  // from the principal point's ground position, along machine x
    double lateral_mm = 0;  // ... along machine y (left)
    double x_mm = 0;        // machine frame
    double y_mm = 0;
};

class CameraModel {
public:
    // A nadir camera at 0.33 mm/px, principal point (0, 0): set it up with
    // nadir() or calibrated() before use.
    CameraModel() = default;

    // Errors (non-positive gsd) as text, never thrown.
    static std::optional<CameraModel> nadir(const NadirParams& p, std::string* error = nullptr);
    // Errors as text: non-positive focal length or height, a pose whose
    // optical axis does not meet the ground.
    static std::optional<CameraModel> calibrated(const Intrinsics& intrinsics, const Pose& pose,
                                                 const Mount& mount, std::string* error = nullptr);

    ModelKind kind() const { return kind_; }
    const Mount& mount() const { return mount_; }

    // Pixel -> ground. nullopt: the pixel's ray does not meet the ground in
    // front of the camera, or the undistortion did not converge.
    std::optional<GroundPoint> pixel_to_ground(cv::Point2d px) const noexcept;
    // Machine-frame ground point (z = 0) -> pixel, distortion included.
    // nullopt: the point is behind the camera. Pixels outside the image are
    // returned as they fall.
    std::optional<cv::Point2d> ground_to_pixel(double x_mm, double y_mm) const noexcept;

    // Calibrated model: camera axes (columns) in the machine frame, and the
    // optical centre in the machine frame (z = height). Nadir: identity pose
    // as the nadir mapping implies, at an undefined height (0).
    const cv::Matx33d& camera_to_machine() const { return r_mc_; }
    const cv::Vec3d& centre_mm() const { return centre_mm_; }
    const Intrinsics& intrinsics() const { return intrinsics_; }

    // Calibrated model: the normalised undistorted image coordinates of a
    // pixel (OpenCV's iterative scheme, run to convergence). Exposed for tests.
    std::optional<cv::Point2d> undistort_normalised(cv::Point2d px) const noexcept;
    // ... and the pixel of normalised coordinates, distortion applied.
    cv::Point2d distort_normalised(cv::Point2d xy) const noexcept;

private:
    ModelKind kind_ = ModelKind::nadir;
    Mount mount_;
    double gsd_mm_per_px_ = 0.33;
    cv::Point2d principal_px_{0, 0};
    Intrinsics intrinsics_;
    cv::Matx33d r_mc_ = cv::Matx33d::eye();  // camera -> machine rotation
    cv::Vec3d centre_mm_{0, 0, 0};
};

// The camera -> machine rotation of a pose and mount (see the conventions).
cv::Matx33d camera_to_machine_rotation(Forward forward, const Pose& pose);

// Reads a camera calibration file, either
//  - OpenCV's calibration YAML/XML (as its calibration sample and
//    stemd-calibrate write it, starting "%YAML:1.0"): camera_matrix (3x3),
//    distortion_coefficients (4, 5, 8 or 12 values), image_width,
//    image_height; or
//  - ROS camera_info YAML, what robot cameras ship with: the same nodes,
//    matrices as {rows, cols, data}, distortion_model plumb_bob or
//    rational_polynomial (an empty distortion list: none).
// Errors as one line of text naming the file and the missing or bad node;
// never throws.
std::optional<Intrinsics> read_calibration(const std::string& path, std::string* error);

}  // namespace stemd::geometry
