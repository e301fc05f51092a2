#include "stemd/geometry/calibration.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgproc.hpp>

#include "one_line.hpp"

namespace stemd::geometry {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;

// cornerSubPix's search window: half the corner spacing at most (a larger
// window reaches the neighbouring corners), and OpenCV's usual 11 px at most.
constexpr double kSubPixWindowFraction = 0.4;
constexpr int kSubPixMaxHalfWindowPx = 11;
constexpr int kSubPixMinHalfWindowPx = 2;

// A listing of the ground corners is a candidate when its reprojection error
// is this close to the best listing's; of those the least turned one wins.
constexpr double kListingRmsFactor = 2.0;
constexpr double kListingRmsSlackPx = 1.0;

void set_error(std::string* error, std::string text)
{
    if (error)
        *error = std::move(text);
}

cv::Matx33d camera_matrix(const Intrinsics& k) { return {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1}; }

std::vector<double> dist_vector(const Intrinsics& k) { return {k.dist.begin(), k.dist.end()}; }

using detail::one_line;

double wrap_deg(double a)
{
    while (a > 180)
        a -= 360;
    while (a <= -180)
        a += 360;
    return a;
}

// The grid's self-maps (i, j) -> (i', j'): turns and flips of a W x H grid
// (a square grid also transposes). Each is a way the finder may have listed
// the corners.
std::vector<std::vector<int>> grid_listings(cv::Size n)
{
    const int w = n.width, h = n.height;
    using Map = cv::Point (*)(int, int, int, int);
    std::vector<Map> maps = {
        [](int i, int j, int, int) { return cv::Point(i, j); },
        [](int i, int j, int w, int h) { return cv::Point(w - 1 - i, h - 1 - j); },
        [](int i, int j, int w, int) { return cv::Point(w - 1 - i, j); },
        [](int i, int j, int, int h) { return cv::Point(i, h - 1 - j); },
    };
    if (w == h) {
        maps.push_back([](int i, int j, int, int) { return cv::Point(j, i); });
        maps.push_back([](int i, int j, int w, int) { return cv::Point(w - 1 - j, w - 1 - i); });
        maps.push_back([](int i, int j, int w, int) { return cv::Point(w - 1 - j, i); });
        maps.push_back([](int i, int j, int w, int) { return cv::Point(j, w - 1 - i); });
    }
    std::vector<std::vector<int>> listings;
    for (const Map map : maps) {
        std::vector<int> to(static_cast<std::size_t>(w * h));
        for (int j = 0; j < h; ++j)
            for (int i = 0; i < w; ++i) {
                const cv::Point p = map(i, j, w, h);
                to[static_cast<std::size_t>(j * w + i)] = p.y * w + p.x;
            }
        listings.push_back(std::move(to));
    }
    return listings;
}

std::string fixed(double v, int decimals)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    std::string s = buf;
    // "-0.000" reads as a sign that is not there.
    if (s.find_first_not_of("-0.") == std::string::npos && s[0] == '-')
        s.erase(0, 1);
    return s;
}

std::string yaml_quoted(const std::string& text)
{
    std::string out = "\"";
    for (const char c : text) {
        if (c == '"' || c == '\\')
            out += '\\';
        out += c;
    }
    return out + "\"";
}

}  // namespace

std::optional<std::string> check_board(const Board& board)
{
    if (board.inner_corners.width < 3 || board.inner_corners.height < 3)
        return std::string("the board needs at least 3x3 inner corners");
    if (!(board.square_mm > 0) || !std::isfinite(board.square_mm))
        return std::string("the board's square size must be positive");
    return std::nullopt;
}

std::vector<cv::Point3f> board_points(const Board& board)
{
    std::vector<cv::Point3f> points;
    points.reserve(static_cast<std::size_t>(board.inner_corners.area()));
    for (int j = 0; j < board.inner_corners.height; ++j)
        for (int i = 0; i < board.inner_corners.width; ++i)
            points.emplace_back(static_cast<float>(i * board.square_mm), static_cast<float>(j * board.square_mm), 0.f);
    return points;
}

std::optional<std::vector<cv::Point2f>> find_board_corners(const cv::Mat& image, cv::Size inner_corners)
{
    if (image.empty() || image.depth() != CV_8U || inner_corners.width < 3 || inner_corners.height < 3)
        return std::nullopt;
    try {
        cv::Mat grey;
        if (image.channels() == 3)
            cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
        else if (image.channels() == 4)
            cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
        else if (image.channels() == 1)
            grey = image;
        else
            return std::nullopt;
        // The classic finder can search a view that shows part of the board
        // (or a board larger than asked for) for minutes, FAST_CHECK or not;
        // the sector-based finder says in a fraction of a second whether the
        // whole board is there, so it decides, and its corners stand in when
        // the classic finder then misses a board it saw.
        std::vector<cv::Point2f> gate;
        if (!cv::findChessboardCornersSB(grey, inner_corners, gate, cv::CALIB_CB_NORMALIZE_IMAGE) ||
            gate.size() != static_cast<std::size_t>(inner_corners.area()))
            return std::nullopt;
        std::vector<cv::Point2f> corners;
        if (!cv::findChessboardCorners(grey, inner_corners, corners,
                                       cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE) ||
            corners.size() != static_cast<std::size_t>(inner_corners.area()))
            return gate;
        double spacing_px = std::numeric_limits<double>::infinity();
        const int w = inner_corners.width;
        for (std::size_t k = 0; k < corners.size(); ++k) {
            const int i = static_cast<int>(k) % w;
            if (i + 1 < w)
                spacing_px = std::min(spacing_px, static_cast<double>(cv::norm(corners[k + 1] - corners[k])));
            if (k + static_cast<std::size_t>(w) < corners.size())
                spacing_px = std::min(spacing_px, static_cast<double>(cv::norm(corners[k + w] - corners[k])));
        }
        const int half = std::clamp(static_cast<int>(kSubPixWindowFraction * spacing_px), kSubPixMinHalfWindowPx,
                                    kSubPixMaxHalfWindowPx);
        cv::cornerSubPix(grey, corners, cv::Size(half, half), cv::Size(-1, -1),
                         cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 100, 1e-4));
        return corners;
    } catch (const cv::Exception&) {
        return std::nullopt;
    }
}

std::optional<IntrinsicsFit> calibrate_intrinsics(const std::vector<std::vector<cv::Point2f>>& views,
                                                  const Board& board, cv::Size image_size, std::string* error)
{
    if (const auto bad = check_board(board)) {
        set_error(error, *bad);
        return std::nullopt;
    }
    if (views.size() < kMinViews) {
        set_error(error, "calibration needs at least " + std::to_string(kMinViews) + " views with the board, got " +
                             std::to_string(views.size()));
        return std::nullopt;
    }
    if (image_size.width <= 0 || image_size.height <= 0) {
        set_error(error, "the image size must be positive");
        return std::nullopt;
    }
    const std::vector<cv::Point3f> object = board_points(board);
    for (std::size_t v = 0; v < views.size(); ++v) {
        if (views[v].size() != object.size()) {
            set_error(error, "view " + std::to_string(v) + " has " + std::to_string(views[v].size()) +
                                 " corners, the board has " + std::to_string(object.size()));
            return std::nullopt;
        }
    }
    try {
        const std::vector<std::vector<cv::Point3f>> objects(views.size(), object);
        cv::Mat k, dist, std_intrinsics, std_extrinsics, per_view;
        std::vector<cv::Mat> rvecs, tvecs;
        const double rms = cv::calibrateCamera(
            objects, views, image_size, k, dist, rvecs, tvecs, std_intrinsics, std_extrinsics, per_view, 0,
            cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, DBL_EPSILON));
        k.convertTo(k, CV_64F);
        dist.convertTo(dist, CV_64F);
        per_view.convertTo(per_view, CV_64F);
        IntrinsicsFit fit;
        fit.intrinsics.fx = k.at<double>(0, 0);
        fit.intrinsics.fy = k.at<double>(1, 1);
        fit.intrinsics.cx = k.at<double>(0, 2);
        fit.intrinsics.cy = k.at<double>(1, 2);
        fit.intrinsics.image_size = image_size;
        const int n = std::min(static_cast<int>(dist.total()), 12);
        for (int i = 0; i < n; ++i)
            fit.intrinsics.dist[static_cast<std::size_t>(i)] = dist.at<double>(i);
        fit.rms_px = rms;
        for (std::size_t v = 0; v < views.size(); ++v)
            fit.view_rms_px.push_back(per_view.at<double>(static_cast<int>(v)));
        if (!std::isfinite(rms) || !(fit.intrinsics.fx > 0) || !(fit.intrinsics.fy > 0)) {
            set_error(error, "the calibration did not converge");
            return std::nullopt;
        }
        return fit;
    } catch (const cv::Exception& e) {
        set_error(error, "calibrateCamera failed: " + one_line(e.what()));
        return std::nullopt;
    }
}

bool write_calibration(const std::string& path, const IntrinsicsFit& fit, std::string* error)
{
    try {
        cv::FileStorage out(path, cv::FileStorage::WRITE);
        if (!out.isOpened()) {
            set_error(error, path + ": cannot open for writing");
            return false;
        }
        const Intrinsics& k = fit.intrinsics;
        out << "image_width" << k.image_size.width << "image_height" << k.image_size.height;
        out << "camera_matrix" << cv::Mat(camera_matrix(k));
        out << "distortion_coefficients" << cv::Mat(std::vector<double>(k.dist.begin(), k.dist.begin() + 5), true);
        out << "avg_reprojection_error" << fit.rms_px;
        out << "nr_of_frames" << static_cast<int>(fit.view_rms_px.size());
        out << "per_view_reprojection_errors" << cv::Mat(fit.view_rms_px, true);
        out.release();
        return true;
    } catch (const cv::Exception& e) {
        set_error(error, path + ": cannot write: " + one_line(e.what()));
        return false;
    }
}

std::vector<cv::Point3d> ground_board_points(const BoardOnGround& ground)
{
    std::vector<cv::Point3d> points;
    for (const cv::Point3f& p : board_points(ground.board))
        points.emplace_back(ground.x_mm + p.x, ground.y_mm + p.y, 0.0);
    return points;
}

Pose pose_from_rotation(const cv::Matx33d& camera_to_machine, Forward forward, double height_mm)
{
    // camera_to_machine = Rz(yaw) Ry(-pitch) Rx(roll) R_forward; R_forward is
    // the pose at zero angles, so strip it and read the Z-Y-X angles.
    const cv::Matx33d r_forward = camera_to_machine_rotation(forward, Pose{});
    const cv::Matx33d m = camera_to_machine * r_forward.t();
    Pose pose;
    pose.height_mm = height_mm;
    pose.pitch_deg = std::asin(std::clamp(m(2, 0), -1.0, 1.0)) * kRadToDeg;
    pose.roll_deg = std::atan2(m(2, 1), m(2, 2)) * kRadToDeg;
    pose.yaw_deg = std::atan2(m(1, 0), m(0, 0)) * kRadToDeg;
    return pose;
}

std::optional<GroundFit> solve_ground_pose(const std::vector<cv::Point2f>& corners, const BoardOnGround& ground,
                                           const Intrinsics& intrinsics, Forward forward, std::string* error)
{
    if (const auto bad = check_board(ground.board)) {
        set_error(error, *bad);
        return std::nullopt;
    }
    const std::vector<cv::Point3d> object = ground_board_points(ground);
    if (corners.size() != object.size()) {
        set_error(error, "got " + std::to_string(corners.size()) + " corners, the board has " +
                             std::to_string(object.size()));
        return std::nullopt;
    }
    const cv::Matx33d k = camera_matrix(intrinsics);
    const std::vector<double> dist = dist_vector(intrinsics);

    struct Candidate {
        cv::Matx33d r_mc;
        cv::Vec3d centre;
        double rms_px;
        Pose pose;
        std::vector<cv::Point2d> image;  // corners in the ground points' order
    };
    std::vector<Candidate> candidates;
    try {
        for (const std::vector<int>& listing : grid_listings(ground.board.inner_corners)) {
            std::vector<cv::Point2d> image(corners.size());
            for (std::size_t f = 0; f < corners.size(); ++f)
                image[static_cast<std::size_t>(listing[f])] = corners[f];
            std::vector<cv::Mat> rvecs, tvecs;
            cv::solvePnPGeneric(object, image, k, dist, rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
            for (std::size_t s = 0; s < rvecs.size(); ++s) {
                cv::Mat rvec = rvecs[s], tvec = tvecs[s];
                cv::solvePnPRefineLM(object, image, k, dist, rvec, tvec);
                cv::Matx33d r_cm;
                cv::Rodrigues(rvec, r_cm);
                const cv::Vec3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
                const cv::Vec3d centre = -(r_cm.t() * t);
                if (!(centre[2] > 0))
                    continue;  // the camera would be below the ground: a mirrored listing
                std::vector<cv::Point2d> projected;
                cv::projectPoints(object, rvec, tvec, k, dist, projected);
                double sum = 0;
                for (std::size_t p = 0; p < image.size(); ++p) {
                    const cv::Point2d d = projected[p] - image[p];
                    sum += d.dot(d);
                }
                const cv::Matx33d r_mc = r_cm.t();
                candidates.push_back({r_mc, centre, std::sqrt(sum / static_cast<double>(image.size())),
                                      pose_from_rotation(r_mc, forward, centre[2]), image});
            }
        }
    } catch (const cv::Exception& e) {
        set_error(error, "solvePnP failed: " + one_line(e.what()));
        return std::nullopt;
    }
    if (candidates.empty()) {
        set_error(error, "no pose puts the camera above the board: is the board face up with its W corners "
                         "forward (+x) and its H corners to the left (+y)?");
        return std::nullopt;
    }
    double best_rms = std::numeric_limits<double>::infinity();
    for (const Candidate& c : candidates)
        best_rms = std::min(best_rms, c.rms_px);
    const double limit = std::max(kListingRmsFactor * best_rms, best_rms + kListingRmsSlackPx);
    const Candidate* chosen = nullptr;
    for (const Candidate& c : candidates)
        if (c.rms_px <= limit && (!chosen || std::abs(wrap_deg(c.pose.yaw_deg)) < std::abs(wrap_deg(chosen->pose.yaw_deg))))
            chosen = &c;

    const cv::Vec3d axis = chosen->r_mc * cv::Vec3d(0, 0, 1);
    if (!(axis[2] < -1e-6)) {
        set_error(error, "the camera's optical axis does not meet the ground");
        return std::nullopt;
    }
    const double t = chosen->centre[2] / -axis[2];
    GroundFit fit;
    fit.pose = chosen->pose;
    fit.mount = {forward, chosen->centre[0] + t * axis[0], chosen->centre[1] + t * axis[1]};

    std::string why;
    const auto model = CameraModel::calibrated(intrinsics, fit.pose, fit.mount, &why);
    if (!model) {
        set_error(error, why);
        return std::nullopt;
    }
    double sum_px = 0, sum_mm = 0;
    for (std::size_t p = 0; p < object.size(); ++p) {
        const auto px = model->ground_to_pixel(object[p].x, object[p].y);
        const auto g = model->pixel_to_ground(chosen->image[p]);
        if (!px || !g) {
            set_error(error, "a board corner does not project through the fitted camera");
            return std::nullopt;
        }
        const cv::Point2d d = *px - chosen->image[p];
        sum_px += d.dot(d);
        const double e = std::hypot(g->x_mm - object[p].x, g->y_mm - object[p].y);
        sum_mm += e * e;
        fit.ground_max_mm = std::max(fit.ground_max_mm, e);
    }
    const double n = static_cast<double>(object.size());
    fit.rms_px = std::sqrt(sum_px / n);
    fit.ground_rms_mm = std::sqrt(sum_mm / n);
    return fit;
}

std::optional<Gsd> gsd_at(const CameraModel& camera, cv::Point2d px)
{
    const auto step = [&](cv::Point2d d) -> std::optional<double> {
        const auto a = camera.pixel_to_ground(px - 0.5 * d);
        const auto b = camera.pixel_to_ground(px + 0.5 * d);
        if (!a || !b)
            return std::nullopt;
        return std::hypot(b->x_mm - a->x_mm, b->y_mm - a->y_mm);
    };
    const auto u = step({1, 0});
    const auto v = step({0, 1});
    if (!u || !v)
        return std::nullopt;
    return Gsd{*u, *v, std::sqrt(*u * *v)};
}

std::array<cv::Point2d, 4> corner_pixels(cv::Size s)
{
    const double r = s.width - 1, b = s.height - 1;
    return {cv::Point2d(0, 0), cv::Point2d(r, 0), cv::Point2d(r, b), cv::Point2d(0, b)};
}

std::array<std::optional<GroundPoint>, 4> ground_footprint(const CameraModel& camera, cv::Size s)
{
    const double l = -0.5, t = -0.5, r = s.width - 0.5, b = s.height - 0.5;
    return {camera.pixel_to_ground({l, t}), camera.pixel_to_ground({r, t}), camera.pixel_to_ground({r, b}),
            camera.pixel_to_ground({l, b})};
}

std::string camera_config_fragment(const GroundFit& fit, const std::string& calibration_file, cv::Size image_size,
                                   double gsd_mm_per_px, const std::vector<std::string>& comment)
{
    std::string out;
    for (const std::string& line : comment)
        out += "# " + line + "\n";
    out += "camera:\n";
    out += "  model: calibrated\n";
    out += "  calibration_file: " + yaml_quoted(calibration_file) + "\n";
    out += "  forward: " + std::string(to_string(fit.mount.forward)) + "\n";
    out += "  height_mm: " + fixed(fit.pose.height_mm, 3) + "\n";
    out += "  roll_deg: " + fixed(fit.pose.roll_deg, 4) + "\n";
    out += "  pitch_deg: " + fixed(fit.pose.pitch_deg, 4) + "\n";
    out += "  yaw_deg: " + fixed(fit.pose.yaw_deg, 4) + "\n";
    out += "  x_mm: " + fixed(fit.mount.x_mm, 3) + "\n";
    out += "  y_mm: " + fixed(fit.mount.y_mm, 3) + "\n";
    out += "  # at the image centre: the detector's sizes in mm (leaf cuts, plant grouping) use it\n";
    out += "  gsd_mm_per_px: " + fixed(gsd_mm_per_px, 5) + "\n";
    out += "# the frame size the calibration is for\n";
    out += "source:\n";
    out += "  width_px: " + std::to_string(image_size.width) + "\n";
    out += "  height_px: " + std::to_string(image_size.height) + "\n";
    return out;
}

}  // namespace stemd::geometry
