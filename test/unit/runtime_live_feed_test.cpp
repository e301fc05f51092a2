// The live view's feed (runtime/live_feed.hpp): frames are lent, not
// copied, and the slot the feed gives back is never one the viewer can
// still see.
#include "stemd/runtime/live_feed.hpp"

#include <atomic>
#include <deque>
#include <set>
#include <thread>

#include <gtest/gtest.h>

using namespace stemd;

namespace {

const runtime::FrameShape kShape{cv::Size(64, 48), vision::Segmentation::chromatic_exg, false};

TEST(LiveFeed, AFrameIsLentWithoutCopyingAndASlotTheViewerCannotSeeComesBack)
{
    runtime::LiveFeed feed(kShape, 1000, 4);
    runtime::FramePool pool(kShape, 4);
    std::deque<drivers::Frame*> free;
    for (std::size_t i = 0; i < pool.size(); ++i)
        free.push_back(&pool[i]);
    std::set<drivers::Frame*> all(free.begin(), free.end());
    const vision::BitMask closed(kShape.size.width, kShape.size.height);
    const drivers::Frame* held = nullptr;   // the viewer's frame
    // A fixed pattern of publications and takes, as a slow viewer and a
    // fast processing thread give.
    const char* const pattern = "ppTpppTTpTpppppTpTTp";
    std::uint64_t seq = 0;
    for (const char* c = pattern; *c != '\0'; ++c) {
        if (*c == 'T') {
            if (feed.take_frame()) {
                held = feed.frame().frame;
                ASSERT_NE(held, nullptr);
                EXPECT_EQ(feed.frame().seq, held->seq);
            }
            continue;
        }
        drivers::Frame* frame = free.front();
        free.pop_front();
        frame->seq = ++seq;
        drivers::Frame* back = feed.publish(frame, vision::Detections{}, closed, nullptr, false, 1);
        ASSERT_NE(back, nullptr);
        EXPECT_NE(back, frame);
        EXPECT_NE(back, held) << "the viewer's frame was given back";
        all.insert(back);   // the feed's own spares join the circulation
        free.push_back(back);
    }
    // After a take, the viewer reads the very slot that was lent.
    drivers::Frame* last = free.front();
    free.pop_front();
    last->seq = ++seq;
    free.push_back(feed.publish(last, vision::Detections{}, closed, nullptr, false, 1));
    ASSERT_TRUE(feed.take_frame());
    EXPECT_EQ(feed.frame().frame, last);
    EXPECT_TRUE(feed.frame().has_image);
    EXPECT_EQ(feed.frame().frame->bgr.data, last->bgr.data) << "the image was copied";
    // Nothing was lost or duplicated: 4 of the caller's and 3 of the feed's.
    EXPECT_EQ(all.size(), 7u);
    std::set<drivers::Frame*> distinct(free.begin(), free.end());
    EXPECT_EQ(distinct.size(), free.size());
    EXPECT_EQ(free.size(), 4u);
}

TEST(LiveFeed, OnlyThePlantsFoundAreCopied)
{
    runtime::LiveFeed feed(kShape, 1000, 4);
    drivers::Frame frame;
    frame.bgr = cv::Mat::zeros(kShape.size, CV_8UC3);
    vision::Detections detections;
    for (int i = 0; i < 3; ++i) {
        vision::Plant p;
        p.stem = {static_cast<float>(10 + i), 20.0f};
        detections.plants.push_back(p);
    }
    const vision::BitMask closed(kShape.size.width, kShape.size.height);
    const PlantClass classes[3] = {PlantClass::Crop, PlantClass::Weed, PlantClass::Unknown};
    feed.publish(&frame, detections, closed, classes, true, 1);
    ASSERT_TRUE(feed.take_frame());
    const runtime::LiveFrame& f = feed.frame();
    ASSERT_EQ(f.detections.plants.size(), 3u);
    EXPECT_EQ(f.detections.plants[2].stem.x, 12.0f);
    EXPECT_EQ(f.plant_class[1], PlantClass::Weed);
}

// Two threads as in the daemon: the processing thread paints each frame it
// gets back with a value, lends it and takes another; the viewer checks
// that every frame it holds keeps the value it was lent with while it reads
// it. A slot given back while still seen would be repainted under it (and
// is a data race under TSan).
TEST(LiveFeed, TheViewersFrameIsNeverRepaintedWhileItReadsIt)
{
    runtime::LiveFeed feed(kShape, 1'000'000'000, 4);
    runtime::FramePool pool(kShape, 3);
    const vision::BitMask closed(kShape.size.width, kShape.size.height);
    constexpr std::uint64_t kFrames = 20000;
    std::atomic<bool> done{false};
    std::uint64_t torn = 0, seen = 0;
    std::thread viewer([&] {
        while (!done.load(std::memory_order_acquire)) {
            if (!feed.take_frame())
                continue;
            const runtime::LiveFrame& f = feed.frame();
            const auto value = static_cast<unsigned char>(f.seq % 251);
            // Read twice: a writer repainting it would show between the two.
            const cv::Mat& bgr = f.frame->bgr;
            for (int pass = 0; pass < 2; ++pass)
                for (int y = 0; y < bgr.rows; ++y) {
                    const unsigned char* row = bgr.ptr<unsigned char>(y);
                    for (int x = 0; x < bgr.cols * 3; ++x)
                        torn += row[x] != value;
                }
            ++seen;
        }
    });
    std::deque<drivers::Frame*> free;
    for (std::size_t i = 0; i < pool.size(); ++i)
        free.push_back(&pool[i]);
    for (std::uint64_t seq = 1; seq <= kFrames; ++seq) {
        drivers::Frame* frame = free.front();
        free.pop_front();
        frame->bgr.setTo(cv::Scalar::all(static_cast<double>(seq % 251)));
        frame->seq = seq;
        free.push_back(feed.publish(frame, vision::Detections{}, closed, nullptr, false, static_cast<std::int64_t>(seq)));
    }
    done.store(true, std::memory_order_release);
    viewer.join();
    EXPECT_EQ(torn, 0u);
    EXPECT_GT(seen, 0u);
}

}  // namespace
