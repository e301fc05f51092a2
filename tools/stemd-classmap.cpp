// stemd-classmap: a colour-coded crop/weed annotation image into a class
// map PNG (0 soil, 1 crop, 2 weed), the format of a recording's class
// column, optionally restricted to a vegetation mask's pixels.
//   stemd-classmap [--crop B,G,R] [--weed B,G,R] [--mask MASK [--mask-vegetation zero|nonzero]]
//                  ANNOTATION OUT
// The defaults are CWFID's colours: crop green (0,255,0), weed red (0,0,255).
#include <cstdio>
#include <iostream>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "stemd/base/plant_class.hpp"
#include "stemd/io/recording.hpp"
#include "tool_cli.hpp"

using namespace stemd;

namespace {

bool parse_bgr(const std::string& text, cv::Vec3b& out)
{
    int b = -1, g = -1, r = -1;
    char tail = 0;
    if (std::sscanf(text.c_str(), "%d,%d,%d%c", &b, &g, &r, &tail) != 3)
        return false;
    for (const int v : {b, g, r})
        if (v < 0 || v > 255)
            return false;
    out = cv::Vec3b(static_cast<std::uint8_t>(b), static_cast<std::uint8_t>(g), static_cast<std::uint8_t>(r));
    return true;
}

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"stemd-classmap: a colour-coded crop/weed annotation into a class map PNG (0 soil, 1 crop, 2 weed)"};
    std::string crop_text = "0,255,0", weed_text = "0,0,255", mask_path, mask_vegetation = "nonzero";
    std::string annotation_path, out_path;
    app.add_option("--crop", crop_text, "B,G,R of crop pixels in the annotation");
    app.add_option("--weed", weed_text, "B,G,R of weed pixels in the annotation");
    app.add_option("--mask", mask_path, "vegetation mask: only its vegetation pixels keep a class");
    app.add_option("--mask-vegetation", mask_vegetation, "which mask value is vegetation")
        ->check(CLI::IsMember({"zero", "nonzero"}));
    app.add_option("ANNOTATION", annotation_path, "colour annotation image")->required();
    app.add_option("OUT", out_path, "class map PNG to write")->required();
    if (const auto exit_code = tools::parse(app, argc, argv, {.tool = "stemd-classmap", .after = " (see --help)"}))
        return *exit_code;
    cv::Vec3b crop, weed;
    if (!parse_bgr(crop_text, crop) || !parse_bgr(weed_text, weed) || crop == weed) {
        std::cerr << "stemd-classmap: --crop and --weed take two different B,G,R triples of 0..255\n";
        return 2;
    }
    std::string error;
    cv::Mat annotation, mask;
    if (!io::load_image(annotation_path, cv::IMREAD_COLOR, annotation, error)) {
        std::cerr << "stemd-classmap: " << error << "\n";
        return 1;
    }
    if (!mask_path.empty()) {
        if (!io::load_image(mask_path, cv::IMREAD_GRAYSCALE, mask, error)) {
            std::cerr << "stemd-classmap: " << error << "\n";
            return 1;
        }
        if (mask.size() != annotation.size()) {
            std::cerr << "stemd-classmap: " << mask_path << ": size differs from " << annotation_path << "\n";
            return 1;
        }
    }
    const bool vegetation_is_zero = mask_vegetation == "zero";
    cv::Mat out(annotation.size(), CV_8UC1, cv::Scalar(0));
    long counts[3] = {0, 0, 0};
    for (int y = 0; y < annotation.rows; ++y) {
        const auto* a = annotation.ptr<cv::Vec3b>(y);
        const std::uint8_t* m = mask.empty() ? nullptr : mask.ptr<std::uint8_t>(y);
        auto* o = out.ptr<std::uint8_t>(y);
        for (int x = 0; x < annotation.cols; ++x) {
            PlantClass c = a[x] == crop ? PlantClass::Crop : a[x] == weed ? PlantClass::Weed : PlantClass::Unknown;
            if (m && ((m[x] == 0) != vegetation_is_zero))
                c = PlantClass::Unknown;
            o[x] = to_value(c);
            ++counts[to_value(c)];
        }
    }
    if (!cv::imwrite(out_path, out)) {
        std::cerr << "stemd-classmap: " << out_path << ": cannot write\n";
        return 1;
    }
    std::cout << out_path << ": " << counts[1] << " crop, " << counts[2] << " weed pixels\n";
    return 0;
}
