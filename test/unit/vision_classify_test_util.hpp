// Helpers shared by the crop/weed tests (plant and cell classifiers): the
// parameters of their synthetic frames, temporary model files, and a plant
// forest saved and read back by OpenCV itself, which the vote checks compare
// the classifier with.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <optional>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "stemd/vision/classify.hpp"

namespace stemd::test {

// 0.3 mm per pixel, small plants kept, pieces 3 mm apart grouped.
inline vision::Params classify_test_params()
{
    vision::Params params;
    params.gsd_mm_per_px = 0.3;
    params.min_plant_area_mm2 = 2;
    params.group_gap_mm = 3;
    return params;
}

// A file name in the temporary directory, unique to this process.
inline std::filesystem::path classify_temp_path(const std::string& prefix, const std::string& name)
{
    return std::filesystem::temp_directory_path() / (prefix + "-" + std::to_string(::getpid()) + "-" + name);
}

// A plant forest of `trees` trees trained on `samples` and `labels`, saved
// to a temporary model file (removed with the fixture), and the same forest
// read back from that file by OpenCV's own RTrees. `model` is empty, with
// `error` set, when training or saving failed.
struct SavedPlantForest {
    SavedPlantForest(const cv::Mat& samples, const cv::Mat& labels, int trees, const std::filesystem::path& file)
        : path(file)
    {
        model = vision::PlantClassifier::train(samples, labels, {.trees = trees}, error);
        if (!model)
            return;
        if (!model->save(path, {.gsd_mm_per_px = 0.3}, error)) {
            model.reset();
            return;
        }
        cv::FileStorage storage(path.string(), cv::FileStorage::READ);
        opencv = cv::ml::RTrees::create();
        opencv->read(storage["forest"]);
    }
    ~SavedPlantForest() { std::filesystem::remove(path); }
    SavedPlantForest(const SavedPlantForest&) = delete;
    SavedPlantForest& operator=(const SavedPlantForest&) = delete;

    std::filesystem::path path;
    std::string error;
    std::optional<vision::PlantClassifier> model;
    cv::Ptr<cv::ml::RTrees> opencv;
};

}  // namespace stemd::test
