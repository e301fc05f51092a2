// Real-time discipline: once a Workspace exists, detect() must not touch
// the heap. Every operator new in this test binary is counted.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <memory>
#include <new>

#include <opencv2/imgproc.hpp>

#include "stemd/vision/detect.hpp"
#include "vision_test_util.hpp"

namespace {
std::atomic<long> g_allocations{0};
}

// This file replaces the global allocation functions: new is malloc, so
// free is the matching release. GCC cannot see that through inlining.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

void* operator new(std::size_t size)
{
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    if (void* p = std::malloc(size == 0 ? 1 : size))
        return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace stemd::vision;

TEST(RealTime, DetectAllocatesNothingOnceTheWorkspaceExists)
{
    const cv::Size size(1296, 966);
    // A busy frame: many plants, noise, vegetation on the border.
    cv::Mat bgr(size, CV_8UC3, cv::Scalar(60, 80, 110));
    const cv::Mat plants = stemd::test::random_blob_mask(size, 77, 150, 0.001);
    bgr.setTo(cv::Scalar(40, 160, 50), plants);
    cv::Mat nir(size, CV_8UC1, cv::Scalar(80));
    nir.setTo(220, plants);

    Params params;
    params.min_plant_area_mm2 = 0;
    params.defect_depth_mm = 0.5;
    params.closing_radius_px = 3;
    params.min_leaves = 2;
    auto ws = std::make_unique<Workspace>(size, params);
    auto out = std::make_unique<Detections>();
    EXPECT_GT(ws->reserved_bytes(), 0u);

    for (const Segmentation seg : {Segmentation::exg, Segmentation::ndvi, Segmentation::mask}) {
        for (const ThresholdMethod t : {ThresholdMethod::otsu, ThresholdMethod::triangle, ThresholdMethod::min_error}) {
            params.segmentation = seg;
            params.threshold = t;
            StageTimes times;
            const FrameView frame{bgr, nir, plants};
            const long before = g_allocations.load();
            detect(frame, params, *ws, *out, &times);
            const long after = g_allocations.load();
            ASSERT_EQ(out->status, DetectStatus::ok);
            EXPECT_GT(out->plants.size(), 10u);
            EXPECT_EQ(after - before, 0) << "heap allocations in detect(): " << to_string(seg) << " " << to_string(t);
        }
    }
}

TEST(RealTime, TheCounterSeesAllocations)
{
    // Guards the test above: if operator new were not replaced it would pass vacuously.
    const long before = g_allocations.load();
    auto p = std::make_unique<int>(3);
    EXPECT_EQ(g_allocations.load() - before, 1);
    EXPECT_EQ(*p, 3);
}
