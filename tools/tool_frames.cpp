#include "tool_frames.hpp"

#include <algorithm>

#include <opencv2/imgcodecs.hpp>

#include "stemd/io/recording.hpp"

namespace fs = std::filesystem;

namespace stemd::tools {

bool collect_frames(const std::vector<std::string>& inputs, vision::Segmentation segmentation,
                    std::vector<FrameJob>& jobs, std::string& error)
{
    for (const std::string& input : inputs) {
        if (io::is_recording_dir(input)) {
            auto rec = io::read_recording(input, error);
            if (!rec)
                return false;
            for (const auto& f : rec->frames) {
                FrameJob job;
                job.image = !f.rgb.empty() ? f.rgb : f.mask;
                if (!f.rgb.empty()) job.rgb = rec->resolve(f.rgb);
                if (!f.nir.empty()) job.nir = rec->resolve(f.nir);
                if (!f.mask.empty()) job.mask = rec->resolve(f.mask);
                if (!f.plant_class.empty()) job.plant_class = rec->resolve(f.plant_class);
                jobs.push_back(std::move(job));
            }
        } else if (fs::is_directory(input)) {
            error = input + ": a directory without frames.csv is not a recording";
            return false;
        } else {
            if (vision::uses_nir(segmentation)) {
                error = input + ": --segment " + std::string(vision::to_string(segmentation)) +
                        " needs a recording directory (its nir column)";
                return false;
            }
            FrameJob job;
            job.image = fs::path(input).filename().string();
            (segmentation == vision::Segmentation::mask ? job.mask : job.rgb) = input;
            jobs.push_back(std::move(job));
        }
    }
    return true;
}

vision::Segmentation frames_segmentation(vision::Segmentation configured, const std::vector<FrameJob>& jobs)
{
    const bool every_nir =
        !jobs.empty() && std::all_of(jobs.begin(), jobs.end(), [](const FrameJob& job) { return !job.nir.empty(); });
    return vision::resolve_segmentation(configured, every_nir);
}

bool load_frame(const FrameJob& job, vision::Segmentation segmentation, bool want_rgb, LoadedFrame& out,
                std::string& error)
{
    out = LoadedFrame{};
    if (segmentation == vision::Segmentation::mask) {
        if (job.mask.empty()) {
            error = job.image + ": no mask for --segment mask";
            return false;
        }
        if (!io::load_image(job.mask, cv::IMREAD_GRAYSCALE, out.mask, error))
            return false;
        return !want_rgb || job.rgb.empty() || io::load_image(job.rgb, cv::IMREAD_COLOR, out.bgr, error);
    }
    if (job.rgb.empty()) {
        error = job.image + ": no rgb image";
        return false;
    }
    if (!io::load_image(job.rgb, cv::IMREAD_COLOR, out.bgr, error))
        return false;
    if (vision::uses_nir(segmentation)) {
        if (job.nir.empty()) {
            error = job.image + ": no nir image for --segment " + std::string(vision::to_string(segmentation));
            return false;
        }
        return io::load_image(job.nir, cv::IMREAD_GRAYSCALE, out.nir, error);
    }
    return true;
}

}  // namespace stemd::tools
