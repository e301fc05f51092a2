// Writes the calibration tests' rendered scenes as PNG files, for the
// end-to-end test of stemd-calibrate:
//   stemd-test-board-views DIR
// DIR/view_00.png .. view_11.png   the intrinsics views (board 9x6, 25 mm)
// DIR/blank.png                    soil without a board
// DIR/ground.png                   the board 11x8, 25 mm, on the ground
// DIR/truth.txt                    the ground camera: height_mm roll_deg pitch_deg yaw_deg x_mm y_mm
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "board_render.hpp"

using namespace stemd::test;

int main(int argc, char** argv)
{
    if (argc != 2) {
        std::cerr << "usage: stemd-test-board-views DIR\n";
        return 2;
    }
    const std::filesystem::path dir = argv[1];
    std::filesystem::create_directories(dir);
    const RenderCamera camera = test_camera();
    const RenderBoard board = test_board();
    for (std::size_t v = 0; v < test_views().size(); ++v) {
        cv::Vec3d rvec, tvec;
        place_board(board, camera, test_views()[v].centre_px, kViewDistanceMm, test_views()[v].rotation, rvec, tvec);
        char name[32];
        std::snprintf(name, sizeof name, "view_%02zu.png", v);
        if (!cv::imwrite((dir / name).string(), render_board(board, camera, rvec, tvec, {0.8, 2.0, 100 + v})))
            return 1;
    }
    if (!cv::imwrite((dir / "blank.png").string(), cv::Mat(camera.size, CV_8U, cv::Scalar(100))))
        return 1;
    const GroundCamera ground;
    cv::Vec3d rvec, tvec;
    ground.board_to_camera(kGroundBoardXMm, kGroundBoardYMm, rvec, tvec);
    if (!cv::imwrite((dir / "ground.png").string(), render_board(ground_test_board(), camera, rvec, tvec, {0.8, 2.0, 7})))
        return 1;
    std::ofstream(dir / "truth.txt") << ground.height_mm << " " << ground.roll_deg << " " << ground.pitch_deg << " "
                                     << ground.yaw_deg << " " << ground.axis_x_mm << " " << ground.axis_y_mm << "\n";
    return 0;
}
