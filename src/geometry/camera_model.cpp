#include "stemd/geometry/camera_model.hpp"

#include <cctype>
#include <cmath>
#include <exception>
#include <string_view>

#include <opencv2/core/persistence.hpp>
#include <yaml-cpp/yaml.h>

#include "one_line.hpp"
#include "stemd/base/enum_names.hpp"
#include "stemd/base/whole_file.hpp"

namespace stemd::geometry {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// Undistortion: OpenCV's fixed-point iteration, run until the pixel it
// reprojects to is this close to the one asked for.
constexpr int kMaxUndistortIterations = 100;
constexpr double kUndistortTolerancePx = 1e-6;
constexpr double kUndistortFailPx = 1e-3;

void set_error(std::string* error, std::string text)
{
    if (error)
        *error = std::move(text);
}

cv::Matx33d rot_x(double a)
{
    const double c = std::cos(a), s = std::sin(a);
    return {1, 0, 0, 0, c, -s, 0, s, c};
}
cv::Matx33d rot_y(double a)
{
    const double c = std::cos(a), s = std::sin(a);
    return {c, 0, s, 0, 1, 0, -s, 0, c};
}
cv::Matx33d rot_z(double a)
{
    const double c = std::cos(a), s = std::sin(a);
    return {c, -s, 0, s, c, 0, 0, 0, 1};
}

// Camera axes (columns: image right, image down, optical axis) in the
// machine frame for a camera looking straight down.
cv::Matx33d forward_rotation(Forward forward)
{
    switch (forward) {
    case Forward::up: return {0, -1, 0, -1, 0, 0, 0, 0, -1};    // right = -y, down = -x
    case Forward::down: return {0, 1, 0, 1, 0, 0, 0, 0, -1};    // right = +y, down = +x
    case Forward::right: return {1, 0, 0, 0, -1, 0, 0, 0, -1};  // right = +x, down = -y
    case Forward::left: return {-1, 0, 0, 0, 1, 0, 0, 0, -1};   // right = -x, down = +y
    }
    return cv::Matx33d::eye();
}

bool finite(double v) { return std::isfinite(v); }

using detail::one_line;

}  // namespace

std::string_view to_string(Forward v) { return base::name_of(kForwardNames, v); }
std::string_view to_string(ModelKind v) { return base::name_of(kModelKindNames, v); }
std::optional<Forward> parse_forward(std::string_view s) { return base::value_of(kForwardNames, s); }
std::optional<ModelKind> parse_model_kind(std::string_view s) { return base::value_of(kModelKindNames, s); }

cv::Point2d image_centre(cv::Size image_size)
{
    return {(image_size.width - 1) / 2.0, (image_size.height - 1) / 2.0};
}

cv::Matx33d camera_to_machine_rotation(Forward forward, const Pose& pose)
{
    return rot_z(pose.yaw_deg * kDegToRad) * rot_y(-pose.pitch_deg * kDegToRad) *
           rot_x(pose.roll_deg * kDegToRad) * forward_rotation(forward);
}

std::optional<CameraModel> CameraModel::nadir(const NadirParams& p, std::string* error)
{
    if (!(p.gsd_mm_per_px > 0) || !finite(p.gsd_mm_per_px)) {
        set_error(error, "nadir camera: gsd_mm_per_px must be positive");
        return std::nullopt;
    }
    if (!finite(p.principal_px.x) || !finite(p.principal_px.y) || !finite(p.mount.x_mm) ||
        !finite(p.mount.y_mm)) {
        set_error(error, "nadir camera: principal point and position must be finite");
        return std::nullopt;
    }
    CameraModel m;
    m.kind_ = ModelKind::nadir;
    m.mount_ = p.mount;
    m.gsd_mm_per_px_ = p.gsd_mm_per_px;
    m.principal_px_ = p.principal_px;
    m.r_mc_ = forward_rotation(p.mount.forward);
    m.centre_mm_ = {p.mount.x_mm, p.mount.y_mm, 0};
    return m;
}

std::optional<CameraModel> CameraModel::calibrated(const Intrinsics& k, const Pose& pose, const Mount& mount,
                                                   std::string* error)
{
    if (!(k.fx > 0) || !(k.fy > 0) || !finite(k.fx) || !finite(k.fy) || !finite(k.cx) || !finite(k.cy)) {
        set_error(error, "calibrated camera: focal lengths must be positive and finite");
        return std::nullopt;
    }
    for (const double d : k.dist) {
        if (!finite(d)) {
            set_error(error, "calibrated camera: distortion coefficients must be finite");
            return std::nullopt;
        }
    }
    if (!(pose.height_mm > 0) || !finite(pose.height_mm)) {
        set_error(error, "calibrated camera: height_mm must be positive");
        return std::nullopt;
    }
    CameraModel m;
    m.kind_ = ModelKind::calibrated;
    m.mount_ = mount;
    m.intrinsics_ = k;
    m.r_mc_ = camera_to_machine_rotation(mount.forward, pose);
    // The optical axis must go down to meet the ground in front of the camera.
    const cv::Vec3d axis = m.r_mc_ * cv::Vec3d(0, 0, 1);
    if (!(axis[2] < -1e-6)) {
        set_error(error, "calibrated camera: the optical axis does not meet the ground (check roll and pitch)");
        return std::nullopt;
    }
    // The principal point's ground position is (x_mm, y_mm): step back up
    // the optical axis to the optical centre.
    const double t = pose.height_mm / -axis[2];
    m.centre_mm_ = {mount.x_mm - t * axis[0], mount.y_mm - t * axis[1], pose.height_mm};
    return m;
}

cv::Point2d CameraModel::distort_normalised(cv::Point2d xy) const noexcept
{
    const auto& d = intrinsics_.dist;
    const double x = xy.x, y = xy.y;
    const double r2 = x * x + y * y, r4 = r2 * r2, r6 = r4 * r2;
    const double radial = (1 + d[0] * r2 + d[1] * r4 + d[4] * r6) / (1 + d[5] * r2 + d[6] * r4 + d[7] * r6);
    const double xd = x * radial + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x) + d[8] * r2 + d[9] * r4;
    const double yd = y * radial + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y + d[10] * r2 + d[11] * r4;
    return {intrinsics_.fx * xd + intrinsics_.cx, intrinsics_.fy * yd + intrinsics_.cy};
}

std::optional<cv::Point2d> CameraModel::undistort_normalised(cv::Point2d px) const noexcept
{
    const auto& d = intrinsics_.dist;
    const double x0 = (px.x - intrinsics_.cx) / intrinsics_.fx;
    const double y0 = (px.y - intrinsics_.cy) / intrinsics_.fy;
    double x = x0, y = y0;
    double error_px = 0;
    for (int i = 0; i < kMaxUndistortIterations; ++i) {
        // As cv::undistortPoints: x = (x0 - tangential/prism(x)) / radial(x).
        const double r2 = x * x + y * y;
        const double icdist =
            (1 + ((d[7] * r2 + d[6]) * r2 + d[5]) * r2) / (1 + ((d[4] * r2 + d[1]) * r2 + d[0]) * r2);
        if (!(icdist > 0))
            return std::nullopt;
        const double dx = 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x) + d[8] * r2 + d[9] * r2 * r2;
        const double dy = d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y + d[10] * r2 + d[11] * r2 * r2;
        x = (x0 - dx) * icdist;
        y = (y0 - dy) * icdist;
        const cv::Point2d back = distort_normalised({x, y});
        error_px = std::hypot(back.x - px.x, back.y - px.y);
        if (!(error_px <= kUndistortTolerancePx))
            continue;
        return cv::Point2d(x, y);
    }
    if (error_px <= kUndistortFailPx && finite(x) && finite(y))
        return cv::Point2d(x, y);
    return std::nullopt;
}

std::optional<GroundPoint> CameraModel::pixel_to_ground(cv::Point2d px) const noexcept
{
    if (!finite(px.x) || !finite(px.y))
        return std::nullopt;
    GroundPoint g;
    if (kind_ == ModelKind::nadir) {
        // Camera frame offset on the ground (x right, y down), then machine axes.
        const cv::Vec3d cam((px.x - principal_px_.x) * gsd_mm_per_px_, (px.y - principal_px_.y) * gsd_mm_per_px_, 0);
        const cv::Vec3d m = r_mc_ * cam;
        g.forward_mm = m[0];
        g.lateral_mm = m[1];
    } else {
        const std::optional<cv::Point2d> n = undistort_normalised(px);
        if (!n)
            return std::nullopt;
        const cv::Vec3d ray = r_mc_ * cv::Vec3d(n->x, n->y, 1);
        if (!(ray[2] < -1e-9))
            return std::nullopt;  // at or above the horizon
        const double t = centre_mm_[2] / -ray[2];
        g.forward_mm = centre_mm_[0] + t * ray[0] - mount_.x_mm;
        g.lateral_mm = centre_mm_[1] + t * ray[1] - mount_.y_mm;
    }
    // -0.0 from the rotation reads badly in logs and tests.
    g.forward_mm += 0.0;
    g.lateral_mm += 0.0;
    g.x_mm = mount_.x_mm + g.forward_mm;
    g.y_mm = mount_.y_mm + g.lateral_mm;
    return g;
}

std::optional<cv::Point2d> CameraModel::ground_to_pixel(double x_mm, double y_mm) const noexcept
{
    if (!finite(x_mm) || !finite(y_mm))
        return std::nullopt;
    if (kind_ == ModelKind::nadir) {
        const cv::Vec3d cam = r_mc_.t() * cv::Vec3d(x_mm - mount_.x_mm, y_mm - mount_.y_mm, 0);
        return cv::Point2d(principal_px_.x + cam[0] / gsd_mm_per_px_, principal_px_.y + cam[1] / gsd_mm_per_px_);
    }
    const cv::Vec3d p = r_mc_.t() * (cv::Vec3d(x_mm, y_mm, 0) - centre_mm_);
    if (!(p[2] > 1e-9))
        return std::nullopt;
    return distort_normalised({p[0] / p[2], p[1] / p[2]});
}

namespace {

// ROS camera_info YAML (camera_calibration_parsers):
//   image_width: 1296
//   image_height: 966
//   camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
//   distortion_model: plumb_bob
//   distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
// rectification_matrix and projection_matrix describe a rectified stereo
// image, not the raw frames stemd reads, and are not used.
std::optional<Intrinsics> read_ros_camera_info(const std::string& path, const std::string& text, std::string* error)
{
    const auto fail = [&](const std::string& what) -> std::optional<Intrinsics> {
        set_error(error, path + ": " + what);
        return std::nullopt;
    };
    YAML::Node root;
    try {
        root = YAML::Load(text);
    } catch (const YAML::ParserException& e) {
        return fail("line " + std::to_string(e.mark.line + 1) + ": invalid YAML: " + e.msg);
    } catch (const std::exception& e) {
        return fail("cannot read: " + one_line(e.what()));
    }
    if (!root.IsMap())
        return fail("not a map of calibration nodes (camera_matrix, distortion_coefficients, image_width, image_height)");
    try {
        Intrinsics k;
        const auto read_int = [&](const char* name, int& out) -> std::optional<std::string> {
            const YAML::Node node = root[name];
            if (!node)
                return std::string("missing node '") + name + "'";
            int v = 0;
            if (!node.IsScalar() || !YAML::convert<int>::decode(node, v))
                return std::string("node '") + name + "' is not an integer";
            out = v;
            return std::nullopt;
        };
        if (auto bad = read_int("image_width", k.image_size.width))
            return fail(*bad);
        if (auto bad = read_int("image_height", k.image_size.height))
            return fail(*bad);
        if (k.image_size.width <= 0 || k.image_size.height <= 0)
            return fail("image_width and image_height must be positive");

        // A matrix node: rows, cols and rows * cols numbers in data (row-major).
        const auto read_matrix = [&](const char* name, int& rows, int& cols,
                                     std::vector<double>& data) -> std::optional<std::string> {
            const std::string key = std::string("node '") + name + "'";
            const YAML::Node node = root[name];
            if (!node)
                return "missing " + key;
            if (!node.IsMap())
                return key + " is not a map with rows, cols and data";
            const YAML::Node r = node["rows"], c = node["cols"], d = node["data"];
            if (!r || !r.IsScalar() || !YAML::convert<int>::decode(r, rows) || rows < 0)
                return key + ": missing or bad 'rows'";
            if (!c || !c.IsScalar() || !YAML::convert<int>::decode(c, cols) || cols < 0)
                return key + ": missing or bad 'cols'";
            if (!d || !d.IsSequence())
                return key + ": missing 'data' list";
            if (d.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols))
                return key + ": 'data' has " + std::to_string(d.size()) + " values, rows x cols is " +
                       std::to_string(rows * cols);
            data.clear();
            for (std::size_t i = 0; i < d.size(); ++i) {
                double v = 0;
                if (!d[i].IsScalar() || !YAML::convert<double>::decode(d[i], v) || !finite(v))
                    return key + ": 'data' value " + std::to_string(i) + " is not a finite number";
                data.push_back(v);
            }
            return std::nullopt;
        };
        int rows = 0, cols = 0;
        std::vector<double> data;
        if (auto bad = read_matrix("camera_matrix", rows, cols, data))
            return fail(*bad);
        if (rows != 3 || cols != 3)
            return fail("node 'camera_matrix' is not a 3x3 matrix");
        k.fx = data[0];
        k.fy = data[4];
        k.cx = data[2];
        k.cy = data[5];
        if (!(k.fx > 0) || !(k.fy > 0))
            return fail("node 'camera_matrix' has a non-positive focal length");

        if (const YAML::Node model = root["distortion_model"]) {
            const std::string name = model.IsScalar() ? model.Scalar() : std::string();
            if (name != "plumb_bob" && name != "rational_polynomial")
                return fail("node 'distortion_model': '" + name +
                            "' is not supported (plumb_bob or rational_polynomial, OpenCV's model)");
        }
        if (auto bad = read_matrix("distortion_coefficients", rows, cols, data))
            return fail(*bad);
        const std::size_t n = data.size();
        if ((rows != 1 && cols != 1 && n != 0) || n == 14)
            return fail(n == 14 ? "node 'distortion_coefficients': the tilted-sensor model (14 values) is not supported"
                                : "node 'distortion_coefficients' is not a vector");
        // ROS leaves the list empty for a camera without distortion.
        if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12)
            return fail("node 'distortion_coefficients' must hold 0, 4, 5, 8 or 12 values");
        for (std::size_t i = 0; i < n; ++i)
            k.dist[i] = data[i];
        return k;
    } catch (const std::exception& e) {
        return fail("cannot read: " + one_line(e.what()));
    }
}

// OpenCV's own files start with its "%YAML:1.0" line (not valid YAML 1.2),
// are XML, or are JSON; the rest is read as ROS camera_info YAML.
bool is_opencv_storage(std::string_view text)
{
    std::size_t i = 0;
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i])))
        ++i;
    const std::string_view start = text.substr(i);
    return start.starts_with("%YAML:") || start.starts_with("<?xml") || start.starts_with("{");
}

// A calibration file is a few kB.
constexpr std::size_t kMaxCalibrationBytes = std::size_t{1} << 20;

}  // namespace

std::optional<Intrinsics> read_calibration(const std::string& path, std::string* error)
{
    const auto fail = [&](const std::string& what) -> std::optional<Intrinsics> {
        set_error(error, path + ": " + what);
        return std::nullopt;
    };
    // Read once here, not by the parsers from the path: they would wait
    // forever on a FIFO and read /dev/zero until the memory is gone.
    std::string text;
    const base::WholeFileResult read = base::read_whole_file(path.c_str(), kMaxCalibrationBytes, text);
    if (!read.ok())
        return fail("cannot read the calibration file: " + base::why_unread(read, kMaxCalibrationBytes));
    if (!is_opencv_storage(text))
        return read_ros_camera_info(path, text, error);
    try {
        cv::FileStorage fs;
        if (!fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY) || !fs.isOpened())
            return fail("cannot open or parse the calibration file");
        Intrinsics k;
        const auto read_int = [&](const char* name, int& out) -> bool {
            const cv::FileNode node = fs[name];
            if (node.empty() || !node.isInt())
                return false;
            out = static_cast<int>(node);
            return true;
        };
        if (!read_int("image_width", k.image_size.width))
            return fail("missing or non-integer node 'image_width'");
        if (!read_int("image_height", k.image_size.height))
            return fail("missing or non-integer node 'image_height'");
        if (k.image_size.width <= 0 || k.image_size.height <= 0)
            return fail("image_width and image_height must be positive");

        const cv::FileNode cm_node = fs["camera_matrix"];
        if (cm_node.empty())
            return fail("missing node 'camera_matrix'");
        cv::Mat cm;
        cm_node >> cm;
        if (cm.rows != 3 || cm.cols != 3 || cm.channels() != 1)
            return fail("node 'camera_matrix' is not a 3x3 matrix");
        cm.convertTo(cm, CV_64F);
        k.fx = cm.at<double>(0, 0);
        k.fy = cm.at<double>(1, 1);
        k.cx = cm.at<double>(0, 2);
        k.cy = cm.at<double>(1, 2);
        if (!(k.fx > 0) || !(k.fy > 0))
            return fail("node 'camera_matrix' has a non-positive focal length");

        const cv::FileNode dist_node = fs["distortion_coefficients"];
        if (dist_node.empty())
            return fail("missing node 'distortion_coefficients'");
        cv::Mat dist;
        dist_node >> dist;
        const int n = dist.empty() || dist.channels() != 1 || (dist.rows != 1 && dist.cols != 1)
            ? -1
            : static_cast<int>(dist.total());
        if (n == 14)
            return fail("node 'distortion_coefficients': the tilted-sensor model (14 values) is not supported");
        if (n != 4 && n != 5 && n != 8 && n != 12)
            return fail("node 'distortion_coefficients' must hold 4, 5, 8 or 12 values");
        dist.convertTo(dist, CV_64F);
        for (int i = 0; i < n; ++i)
            k.dist[static_cast<std::size_t>(i)] = dist.at<double>(i);
        for (const double v : k.dist)
            if (!finite(v))
                return fail("node 'distortion_coefficients' has a non-finite value");
        return k;
    } catch (const std::exception& e) {
        return fail("cannot read: " + one_line(e.what()));
    } catch (...) {
        return fail("cannot read: unknown error");
    }
}

}  // namespace stemd::geometry
