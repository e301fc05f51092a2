// What the tools share: turning INPUT arguments (images or recording
// directories) into frames, and loading a frame's images.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "stemd/vision/types.hpp"

namespace stemd::tools {

struct FrameJob {
    std::string image;   // the frame's name in CSVs: as written in frames.csv, or the basename
    std::filesystem::path rgb, nir, mask;
    std::filesystem::path plant_class;   // a recording's class column; empty when none
};

// Expands INPUTs: a recording directory gives its frames, an image file one
// frame (the mask itself with mask segmentation). False + error on a bad
// recording or an input the segmentation cannot use.
bool collect_frames(const std::vector<std::string>& inputs, vision::Segmentation segmentation,
                    std::vector<FrameJob>& jobs, std::string& error);

// The method `configured` runs on these frames: segment.method auto is
// exg_and_ndvi when every frame has a nir image and chromatic_exg
// otherwise (image files have none); any other method stays.
vision::Segmentation frames_segmentation(vision::Segmentation configured, const std::vector<FrameJob>& jobs);

struct LoadedFrame {
    cv::Mat bgr, nir, mask;
};

// Loads the images the segmentation needs (and the rgb image for mask
// segmentation when want_rgb). Resolve auto first (frames_segmentation). False + error naming the file if unreadable.
bool load_frame(const FrameJob& job, vision::Segmentation segmentation, bool want_rgb, LoadedFrame& out,
                std::string& error);

}  // namespace stemd::tools
