// Real-time discipline: mapping pixels and querying odometry never touch
// the heap. Every operator new in this test binary is counted.
#include <gtest/gtest.h>

#include "counting_new.hpp"

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "stemd/geometry/camera_model.hpp"
#include "stemd/geometry/field.hpp"
#include "stemd/geometry/odometry.hpp"


using namespace stemd::geometry;

TEST(GeometryRealTime, MappingAndOdometryAllocateNothing)
{
    Intrinsics k;
    k.fx = k.fy = 1000;
    k.cx = 640;
    k.cy = 480;
    k.image_size = {1280, 960};
    k.dist = {-0.1, 0.03, 0.001, 0.001, -0.01, 0, 0, 0, 0, 0, 0, 0};
    const auto cal = CameraModel::calibrated(k, {500, 3, 15, 5}, {Forward::up, 200, 0});
    NadirParams np;
    np.principal_px = image_centre({1280, 960});
    const auto nad = CameraModel::nadir(np);
    ASSERT_TRUE(cal && nad);
    OdometryRing ring({128, 100'000'000});

    const long before = stemd::test::allocations();
    double sum = 0;
    for (int i = 0; i < 1000; ++i) {
        ring.push({static_cast<std::int64_t>(i) * 1'000'000, i * 0.5});
        const cv::Point2f px(static_cast<float>(i % 1280), static_cast<float>((i * 7) % 960));
        for (const CameraModel* m : {&*cal, &*nad}) {
            if (const auto g = m->pixel_to_ground(px))
                if (const auto back = m->ground_to_pixel(g->x_mm, g->y_mm))
                    sum += back->x;
            if (const auto f = field_position(*m, px, ring.odom_at(i * 1'000'000 - 500'000).odom_mm))
                sum += f->s_mm;
        }
        sum += ring.speed_mm_per_s(20'000'000);
    }
    EXPECT_EQ(stemd::test::allocations() - before, 0);
    EXPECT_TRUE(std::isfinite(sum));
}
