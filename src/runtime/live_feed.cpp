#include "stemd/runtime/live_feed.hpp"

#include <algorithm>
#include <cstring>

namespace stemd::runtime {

LiveFeed::LiveFeed(cv::Size frame_size, int fps, std::size_t plant_capacity)
    : frame_size_(frame_size),
      min_interval_ns_(1'000'000'000 / std::max(fps, 1)),
      frames_([frame_size](LiveFrame& slot) {
          slot.bgr.create(frame_size, CV_8UC3);
          slot.closed.reset(frame_size.width, frame_size.height);
      }),
      plants_(std::max<std::size_t>(plant_capacity, 1)),
      targets_(std::max<std::size_t>(plant_capacity, 1))
{
}

void LiveFeed::publish(const drivers::Frame& frame, const vision::Detections& detections,
                       const vision::BitMask& closed, const PlantClass* plant_class, bool has_class,
                       std::int64_t now_ns)
{
    last_published_ns_ = now_ns;
    LiveFrame& slot = frames_.write_slot();
    slot.seq = frame.seq;
    slot.t_sample_ns = frame.t_sample_ns;
    slot.t_published_ns = now_ns;
    slot.odom_mm = frame.odom_mm;
    slot.name = frame.name;
    // Same size and type: copyTo writes into the slot's own buffer.
    slot.has_image = frame.bgr.size() == frame_size_ && frame.bgr.type() == CV_8UC3;
    if (slot.has_image)
        frame.bgr.copyTo(slot.bgr);
    if (closed.width() == slot.closed.width() && closed.height() == slot.closed.height())
        std::memcpy(slot.closed.row(0), closed.row(0),
                    static_cast<std::size_t>(closed.height()) * closed.words_per_row() * sizeof(std::uint64_t));
    else
        slot.closed.clear();
    slot.detections = detections;
    slot.has_class = has_class;
    if (has_class)
        std::copy_n(plant_class, detections.plants.size(), slot.plant_class.begin());
    frames_.publish();
}

}  // namespace stemd::runtime
