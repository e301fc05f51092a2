// stemd-calibrate: the camera's intrinsics from chessboard views, and its
// pose above the ground from one view of a board lying on the ground.
//   stemd-calibrate intrinsics --board WxH --square-mm S --out FILE IMAGES...
//   stemd-calibrate ground --board WxH --square-mm S --calibration FILE
//                   --board-x-mm X --board-y-mm Y [--forward up|down|left|right] --out FRAGMENT IMAGE
// The work is in stemd/geometry/calibration.hpp; this wires files to it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/config/config.hpp"
#include "stemd/geometry/calibration.hpp"
#include "stemd/geometry/camera_model.hpp"
#include "stemd/io/recording.hpp"
#include "tool_cli.hpp"

namespace fs = std::filesystem;
using namespace stemd;

namespace {

constexpr int kOk = 0;
constexpr int kFailed = 1;      // the board was not found, too few views, no pose, output not written
using tools::kUsageError;  // bad arguments, unreadable or malformed input

// Below this many views calibrateCamera runs but pins little down.
constexpr std::size_t kRecommendedViews = 10;
// A view this many times worse than the whole fit is worth a look.
constexpr double kSuspectViewFactor = 3.0;
// Warn when the camera is turned more than this from camera.forward.
constexpr double kYawWarnDeg = 45.0;

struct UsageError {
    std::string message;
};

cv::Size parse_board(const std::string& text)
{
    const std::size_t x = text.find_first_of("xX");
    long w = 0, h = 0;
    if (x == std::string::npos || !tools::parse_int(text.substr(0, x), w) || !tools::parse_int(text.substr(x + 1), h) ||
        w < 3 || h < 3 || w > 100 || h > 100)
        throw UsageError{"--board: expected WxH inner corners, each 3..100 (e.g. 9x6), got '" + text + "'"};
    return {static_cast<int>(w), static_cast<int>(h)};
}

geometry::Board board_of(const std::string& board_text, double square_mm)
{
    geometry::Board board{parse_board(board_text), square_mm};
    if (const auto bad = geometry::check_board(board))
        throw UsageError{"--square-mm: " + *bad};
    return board;
}

// Through the readers' one checked loader: the size in the header, a file
// cut off, errno.
cv::Mat read_image(const std::string& path)
{
    cv::Mat image;
    if (std::string error; !io::load_image(path, cv::IMREAD_GRAYSCALE, image, error))
        throw UsageError{error};
    return image;
}

std::string num(double v, int decimals)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

std::string size_text(cv::Size s) { return std::to_string(s.width) + "x" + std::to_string(s.height); }

// --- intrinsics ------------------------------------------------------------------

struct IntrinsicsArgs {
    std::string board;
    double square_mm = 0;
    std::string out;
    std::vector<std::string> images;
};

int run_intrinsics(const IntrinsicsArgs& args)
{
    const geometry::Board board = board_of(args.board, args.square_mm);
    std::vector<std::vector<cv::Point2f>> views;
    std::vector<std::string> used;
    cv::Size size;
    for (const std::string& path : args.images) {
        const cv::Mat image = read_image(path);
        if (size.empty())
            size = image.size();
        else if (image.size() != size)
            throw UsageError{path + ": the image is " + size_text(image.size()) + ", the first one " + size_text(size)};
        auto corners = geometry::find_board_corners(image, board.inner_corners);
        if (!corners) {
            std::cout << path << ": board " << args.board << " not found, view rejected\n";
            continue;
        }
        std::cout << path << ": board found\n";
        views.push_back(std::move(*corners));
        used.push_back(path);
    }
    std::cout << views.size() << " of " << args.images.size() << " views show the board\n";
    if (views.size() < geometry::kMinViews) {
        std::cerr << "stemd-calibrate: at least " << geometry::kMinViews << " views with the whole board are needed ("
                  << kRecommendedViews << " or more, tilted and across the whole image, recommended)\n";
        return kFailed;
    }
    if (views.size() < kRecommendedViews)
        std::cout << "warning: " << views.size() << " views; " << kRecommendedViews
                  << " or more, tilted and across the whole image, pin the distortion down better\n";
    std::string error;
    const auto fit = geometry::calibrate_intrinsics(views, board, size, &error);
    if (!fit) {
        std::cerr << "stemd-calibrate: " << error << "\n";
        return kFailed;
    }
    const geometry::Intrinsics& k = fit->intrinsics;
    std::cout << "image " << size_text(size) << "\n"
              << "fx " << num(k.fx, 3) << " px, fy " << num(k.fy, 3) << " px, cx " << num(k.cx, 3) << " px, cy "
              << num(k.cy, 3) << " px\n"
              << "distortion k1 k2 p1 p2 k3: " << num(k.dist[0], 6) << " " << num(k.dist[1], 6) << " "
              << num(k.dist[2], 6) << " " << num(k.dist[3], 6) << " " << num(k.dist[4], 6) << "\n"
              << "RMS reprojection error " << num(fit->rms_px, 4) << " px over " << views.size() << " views\n";
    for (std::size_t v = 0; v < used.size(); ++v) {
        const double e = fit->view_rms_px[v];
        std::cout << "  " << used[v] << ": " << num(e, 4) << " px"
                  << (e > kSuspectViewFactor * fit->rms_px ? "  (well above the rest: check this view)" : "") << "\n";
    }
    if (!geometry::write_calibration(args.out, *fit, &error)) {
        std::cerr << "stemd-calibrate: " << error << "\n";
        return kFailed;
    }
    std::cout << "wrote " << args.out << "\n";
    return kOk;
}

// --- ground -------------------------------------------------------------------------

struct GroundArgs {
    std::string board;
    double square_mm = 0;
    std::string calibration;
    double board_x_mm = 0;
    double board_y_mm = 0;
    std::string forward = "up";
    std::string out;
    std::string image;
};

int run_ground(const GroundArgs& args)
{
    const geometry::Board board = board_of(args.board, args.square_mm);
    if (!std::isfinite(args.board_x_mm) || !std::isfinite(args.board_y_mm))
        throw UsageError{"--board-x-mm and --board-y-mm must be finite"};
    const auto forward = geometry::parse_forward(args.forward);
    if (!forward)
        throw UsageError{"--forward: expected up, down, left or right, got '" + args.forward + "'"};
    std::string error;
    const auto intrinsics = geometry::read_calibration(args.calibration, &error);
    if (!intrinsics)
        throw UsageError{error};
    const cv::Mat image = read_image(args.image);
    if (image.size() != intrinsics->image_size)
        throw UsageError{args.image + ": the image is " + size_text(image.size()) + ", " + args.calibration +
                         " is calibrated for " + size_text(intrinsics->image_size)};

    const auto corners = geometry::find_board_corners(image, board.inner_corners);
    if (!corners) {
        std::cerr << "stemd-calibrate: " << args.image << ": board " << args.board << " not found\n";
        return kFailed;
    }
    const geometry::BoardOnGround ground{board, args.board_x_mm, args.board_y_mm};
    const auto fit = geometry::solve_ground_pose(*corners, ground, *intrinsics, *forward, &error);
    if (!fit) {
        std::cerr << "stemd-calibrate: " << args.image << ": " << error << "\n";
        return kFailed;
    }
    const auto camera = geometry::CameraModel::calibrated(*intrinsics, fit->pose, fit->mount, &error);
    if (!camera) {
        std::cerr << "stemd-calibrate: " << error << "\n";
        return kFailed;
    }
    const geometry::Pose& p = fit->pose;
    std::cout << "pose: height " << num(p.height_mm, 1) << " mm, roll " << num(p.roll_deg, 2) << " deg, pitch "
              << num(p.pitch_deg, 2) << " deg, yaw " << num(p.yaw_deg, 2) << " deg (forward " << args.forward << ")\n"
              << "principal point on the ground: x " << num(fit->mount.x_mm, 1) << " mm, y "
              << num(fit->mount.y_mm, 1) << " mm (machine frame: x forward, y left)\n"
              << "board corners: reprojection RMS " << num(fit->rms_px, 3) << " px; on the ground RMS "
              << num(fit->ground_rms_mm, 2) << " mm, max " << num(fit->ground_max_mm, 2) << " mm\n";
    if (std::abs(p.yaw_deg) > kYawWarnDeg)
        std::cout << "warning: the camera is turned " << num(p.yaw_deg, 1)
                  << " deg from --forward " << args.forward << ": is --forward right?\n";

    const cv::Size size = intrinsics->image_size;
    const auto centre_gsd = geometry::gsd_at(*camera, geometry::image_centre(size));
    if (!centre_gsd) {
        std::cerr << "stemd-calibrate: the image centre does not see the ground\n";
        return kFailed;
    }
    const char* const corner_names[4] = {"top left", "top right", "bottom right", "bottom left"};
    const auto gsd_line = [](const char* name, const std::optional<geometry::Gsd>& g) {
        std::printf("  %-13s", name);
        if (g)
            std::printf("%.4f / %.4f / %.4f\n", g->along_u_mm_per_px, g->along_v_mm_per_px, g->mean_mm_per_px);
        else
            std::printf("does not see the ground\n");
    };
    std::cout << "GSD in mm/px (along image u / along v / geometric mean):\n";
    std::fflush(stdout);
    gsd_line("centre", centre_gsd);
    const auto corner_px = geometry::corner_pixels(size);
    for (int c = 0; c < 4; ++c)
        gsd_line(corner_names[c], geometry::gsd_at(*camera, corner_px[static_cast<std::size_t>(c)]));
    std::printf("ground footprint of the image's corners (machine frame, mm):\n");
    const auto footprint = geometry::ground_footprint(*camera, size);
    for (int c = 0; c < 4; ++c) {
        const auto& g = footprint[static_cast<std::size_t>(c)];
        std::printf("  %-13s", corner_names[c]);
        if (g)
            std::printf("x %8.1f  y %8.1f\n", g->x_mm, g->y_mm);
        else
            std::printf("above the horizon\n");
    }
    std::fflush(stdout);

    std::error_code ec;
    const fs::path calibration = fs::absolute(args.calibration, ec);
    const std::string fragment = geometry::camera_config_fragment(
        *fit, ec ? args.calibration : calibration.lexically_normal().string(), size, centre_gsd->mean_mm_per_px,
        {"stemd-calibrate ground: " + args.image + ", board " + args.board + " of " + num(board.square_mm, 2) +
             " mm squares, first inner corner at x " + num(args.board_x_mm, 1) + " mm, y " +
             num(args.board_y_mm, 1) + " mm",
         "board corners: reprojection RMS " + num(fit->rms_px, 3) + " px, on the ground RMS " +
             num(fit->ground_rms_mm, 2) + " mm"});
    // The fragment must be one the configuration takes (its ranges included).
    config::Config check;
    if (const auto bad = check.load_text(fragment, args.out)) {
        std::cerr << "stemd-calibrate: the fitted camera is outside the configuration's ranges: " << bad->to_string()
                  << "\n";
        return kFailed;
    }
    std::ofstream out(args.out, std::ios::binary | std::ios::trunc);
    out << fragment;
    out.close();
    if (!out) {
        std::cerr << "stemd-calibrate: " << args.out << ": cannot write\n";
        return kFailed;
    }
    std::cout << "wrote " << args.out << " (check it: stemd --config " << args.out << " --check-config)\n";
    return kOk;
}

// The board both subcommands take: its inner corners and its square size.
void add_board_options(CLI::App& cmd, std::string& board, double& square_mm)
{
    cmd.add_option("--board", board, "inner corners WxH (OpenCV's pattern size), e.g. 9x6")->required();
    cmd.add_option("--square-mm", square_mm, "side of one square in mm")->required();
}

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"stemd-calibrate: camera intrinsics from chessboard views, and the camera's pose above the ground "
                 "from one view of a board lying on the ground.\n"
                 "Exit status: 0 done, 1 the board was not found or the fit failed, 2 bad arguments or unreadable "
                 "input."};
    app.require_subcommand(1);

    IntrinsicsArgs intrinsics;
    CLI::App* intr = app.add_subcommand(
        "intrinsics", "chessboard calibration (OpenCV calibrateCamera): writes OpenCV's calibration YAML, which "
                      "camera.calibration_file reads");
    add_board_options(*intr, intrinsics.board, intrinsics.square_mm);
    intr->add_option("--out", intrinsics.out, "calibration YAML to write")->required();
    intr->add_option("images", intrinsics.images, "views of the board (10 or more, tilted, across the image)")
        ->required();

    GroundArgs ground;
    CLI::App* gnd = app.add_subcommand(
        "ground", "camera pose from one view of the board lying flat on the ground: its W corners forward (+x), "
                  "its H corners to the left (+y); writes a config fragment (camera and source sections)");
    add_board_options(*gnd, ground.board, ground.square_mm);
    gnd->add_option("--calibration", ground.calibration,
                    "intrinsics: OpenCV calibration YAML (stemd-calibrate intrinsics) or ROS camera_info YAML")
        ->required();
    gnd->add_option("--board-x-mm", ground.board_x_mm,
                    "machine x (forward) of the board's first inner corner, the rear-right one")
        ->required();
    gnd->add_option("--board-y-mm", ground.board_y_mm, "machine y (left) of that corner")->required();
    gnd->add_option("--forward", ground.forward, "image direction that points forward (camera.forward)")
        ->default_val("up");
    gnd->add_option("--out", ground.out, "config fragment to write")->required();
    gnd->add_option("image", ground.image, "the view of the board on the ground")->required();

    if (const auto exit_code =
            tools::parse(app, argc, argv, {.tool = "stemd-calibrate", .after = "\n(stemd-calibrate --help for usage)"}))
        return *exit_code;
    try {
        if (intr->parsed())
            return run_intrinsics(intrinsics);
        return run_ground(ground);
    } catch (const UsageError& e) {
        std::cerr << "stemd-calibrate: " << e.message << "\n";
        return kUsageError;
    }
}
