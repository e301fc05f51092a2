#include "board_render.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace stemd::test {

namespace {

constexpr double kBlack = 40, kWhite = 210, kBackground = 100;

// The board's square wave (+1 on squares whose column index is even) along
// one axis, averaged over a window `width_mm` wide around `x`: a pixel's
// footprint on the board, so that the edges are anti-aliased.
double smooth_square(double x, double square_mm, double width_mm)
{
    const double k = std::round(x / square_mm);
    const double e = x - k * square_mm;  // signed distance from the nearest edge
    const double w = std::clamp(width_mm, 1e-9, square_mm);
    const double sign = (static_cast<long>(k) % 2 == 0) ? 1.0 : -1.0;
    return sign * std::clamp(2 * e / w, -1.0, 1.0);
}

// Every pixel centre's undistorted normalised coordinates: the same for
// every view of one camera, so computed once per camera.
const std::vector<cv::Point2d>& normalised_pixels(const RenderCamera& camera)
{
    static RenderCamera cached;
    static std::vector<cv::Point2d> normalised;
    if (!normalised.empty() && cached.k == camera.k && cached.dist == camera.dist && cached.size == camera.size)
        return normalised;
    const int w = camera.size.width, h = camera.size.height;
    std::vector<cv::Point2d> pixels;
    pixels.reserve(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    for (int v = 0; v < h; ++v)
        for (int u = 0; u < w; ++u)
            pixels.emplace_back(u, v);
    cv::undistortPoints(pixels, normalised, camera.k, camera.dist, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-9));
    cached = camera;
    return normalised;
}

}  // namespace

std::vector<cv::Point2d> true_corners(const RenderBoard& board, const RenderCamera& camera, const cv::Vec3d& rvec,
                                      const cv::Vec3d& tvec)
{
    std::vector<cv::Point3d> object;
    for (int j = 0; j < board.inner_corners.height; ++j)
        for (int i = 0; i < board.inner_corners.width; ++i)
            object.emplace_back(i * board.square_mm, j * board.square_mm, 0.0);
    std::vector<cv::Point2d> image;
    cv::projectPoints(object, rvec, tvec, camera.k, camera.dist, image);
    return image;
}

void place_board(const RenderBoard& board, const RenderCamera& camera, cv::Point2d centre_px, double distance_mm,
                 const cv::Vec3d& rotation, cv::Vec3d& rvec, cv::Vec3d& tvec)
{
    cv::Matx33d r;
    cv::Rodrigues(rotation, r);
    const cv::Vec3d centre_board((board.inner_corners.width - 1) * board.square_mm / 2,
                                 (board.inner_corners.height - 1) * board.square_mm / 2, 0);
    cv::Vec3d ray = camera.k.inv() * cv::Vec3d(centre_px.x, centre_px.y, 1);
    ray = ray / cv::norm(ray);
    tvec = distance_mm * ray - r * centre_board;
    cv::Rodrigues(r, rvec);
}

cv::Mat render_board(const RenderBoard& board, const RenderCamera& camera, const cv::Vec3d& rvec,
                     const cv::Vec3d& tvec, const RenderNoise& noise)
{
    const int w = camera.size.width, h = camera.size.height;
    const std::vector<cv::Point2d>& normalised = normalised_pixels(camera);

    // Board plane -> normalised image: [r1 r2 t]; its inverse takes each ray
    // to the board point it sees.
    cv::Matx33d r;
    cv::Rodrigues(rvec, r);
    const cv::Matx33d hom(r(0, 0), r(0, 1), tvec[0], r(1, 0), r(1, 1), tvec[1], r(2, 0), r(2, 1), tvec[2]);
    const cv::Matx33d inv = hom.inv();
    cv::Mat bx(h, w, CV_64F), by(h, w, CV_64F);
    cv::Mat in_front(h, w, CV_8U);
    for (int v = 0; v < h; ++v)
        for (int u = 0; u < w; ++u) {
            const cv::Point2d& n = normalised[static_cast<std::size_t>(v) * static_cast<std::size_t>(w) +
                                              static_cast<std::size_t>(u)];
            const cv::Vec3d b = inv * cv::Vec3d(n.x, n.y, 1);
            in_front.at<uchar>(v, u) = b[2] > 0;
            bx.at<double>(v, u) = b[0] / b[2];
            by.at<double>(v, u) = b[1] / b[2];
        }

    const double s = board.square_mm, m = board.margin_mm;
    const double x_hi = board.inner_corners.width * s, y_hi = board.inner_corners.height * s;
    cv::Mat image(h, w, CV_32F);
    for (int v = 0; v < h; ++v)
        for (int u = 0; u < w; ++u) {
            float& out = image.at<float>(v, u);
            out = static_cast<float>(kBackground);
            if (!in_front.at<uchar>(v, u))
                continue;
            const double x = bx.at<double>(v, u), y = by.at<double>(v, u);
            if (x < -s - m || x > x_hi + m || y < -s - m || y > y_hi + m)
                continue;
            if (x < -s || x > x_hi || y < -s || y > y_hi) {
                out = static_cast<float>(kWhite);
                continue;
            }
            // The pixel's footprint on the board, from its neighbours.
            const int ul = std::max(u - 1, 0), ur = std::min(u + 1, w - 1);
            const int vu = std::max(v - 1, 0), vd = std::min(v + 1, h - 1);
            const double du = 1.0 / (ur - ul), dv = 1.0 / (vd - vu);
            const double wx = std::abs(bx.at<double>(v, ur) - bx.at<double>(v, ul)) * du +
                              std::abs(bx.at<double>(vd, u) - bx.at<double>(vu, u)) * dv;
            const double wy = std::abs(by.at<double>(v, ur) - by.at<double>(v, ul)) * du +
                              std::abs(by.at<double>(vd, u) - by.at<double>(vu, u)) * dv;
            const double p = smooth_square(x, s, wx) * smooth_square(y, s, wy);  // +1: a dark square
            out = static_cast<float>((kBlack + kWhite) / 2 - (kWhite - kBlack) / 2 * p);
        }
    if (noise.blur_sigma_px > 0)
        cv::GaussianBlur(image, image, cv::Size(), noise.blur_sigma_px);
    if (noise.noise_sigma > 0) {
        cv::Mat n(h, w, CV_32F);
        cv::RNG rng(noise.seed);
        rng.fill(n, cv::RNG::NORMAL, 0.0, noise.noise_sigma);
        image += n;
    }
    cv::Mat grey;
    image.convertTo(grey, CV_8U);  // rounds and saturates
    return grey;
}

RenderCamera test_camera()
{
    RenderCamera c;
    c.k = {1050, 0, 652.3, 0, 1046, 478.9, 0, 0, 1};
    c.dist = {-0.11, 0.07, 0.0006, -0.0004, -0.02};
    c.size = {1296, 966};
    return c;
}

const std::vector<ViewSpec>& test_views()
{
    static const std::vector<ViewSpec> views = {
        {{400, 300}, {0.45, 0.30, 0.00}},  {{900, 300}, {0.40, -0.35, 0.20}}, {{400, 670}, {-0.40, 0.35, -0.20}},
        {{900, 670}, {-0.45, -0.30, 0.10}}, {{648, 483}, {0.00, 0.50, 0.30}},   {{470, 483}, {0.50, 0.00, -0.10}},
        {{830, 483}, {-0.50, 0.00, 0.00}},  {{648, 330}, {0.20, -0.45, 1.57}},  {{648, 640}, {-0.20, 0.45, -0.30}},
        {{380, 483}, {0.35, 0.20, 0.05}},   {{920, 483}, {-0.35, -0.20, 0.40}}, {{648, 483}, {0.10, -0.10, 0.00}},
    };
    return views;
}

RenderBoard test_board() { return {{9, 6}, 25, 15}; }
RenderBoard ground_test_board() { return {{11, 8}, 25, 15}; }

namespace {
cv::Matx33d rodrigues(double ax, double ay, double az)
{
    cv::Matx33d r;
    cv::Rodrigues(cv::Vec3d(ax, ay, az), r);
    return r;
}
constexpr double kDeg = 3.14159265358979323846 / 180;
}  // namespace

cv::Matx33d GroundCamera::camera_to_machine() const
{
    const cv::Matx33d base(0, -1, 0, -1, 0, 0, 0, 0, -1);
    return rodrigues(0, 0, yaw_deg * kDeg) * rodrigues(0, -pitch_deg * kDeg, 0) * rodrigues(roll_deg * kDeg, 0, 0) *
           base;
}

cv::Vec3d GroundCamera::centre_mm() const
{
    const cv::Matx33d r = camera_to_machine();
    const cv::Vec3d axis(r(0, 2), r(1, 2), r(2, 2));
    const double t = height_mm / -axis[2];
    return {axis_x_mm - t * axis[0], axis_y_mm - t * axis[1], height_mm};
}

void GroundCamera::board_to_camera(double board_x_mm, double board_y_mm, cv::Vec3d& rvec, cv::Vec3d& tvec) const
{
    // The board's axes are the machine's: only its origin moves.
    const cv::Matx33d r_cm = camera_to_machine().t();
    cv::Rodrigues(r_cm, rvec);
    tvec = r_cm * (cv::Vec3d(board_x_mm, board_y_mm, 0) - centre_mm());
}

}  // namespace stemd::test
