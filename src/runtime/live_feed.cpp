#include "stemd/runtime/live_feed.hpp"

#include <algorithm>
#include <cstring>

namespace stemd::runtime {

LiveFeed::LiveFeed(const FrameShape& shape, int fps, std::size_t plant_capacity)
    : frame_size_(shape.size),
      min_interval_ns_(1'000'000'000 / std::max(fps, 1)),
      spare_slots_(shape, 3),
      // Each slot starts with a spare frame: the writer's is what the first
      // publish() gives back, and a slot the writer gets back later holds a
      // frame the reader has let go of.
      frames_([this, next = std::size_t{0}](LiveFrame& slot) mutable {
          slot.closed.reset(frame_size_.width, frame_size_.height);
          slot.frame = &spare_slots_[next++];
      }),
      plants_(std::max<std::size_t>(plant_capacity, 1)),
      targets_(std::max<std::size_t>(plant_capacity, 1))
{
}

drivers::Frame* LiveFeed::publish(drivers::Frame* frame, const vision::Detections& detections,
                                  const vision::BitMask& closed, const PlantClass* plant_class, bool has_class,
                                  std::int64_t now_ns)
{
    last_published_ns_ = now_ns;
    LiveFrame& slot = frames_.write_slot();
    // The reader never sees the write slot: its frame is free.
    drivers::Frame* const given_back = slot.frame;
    slot.frame = frame;
    slot.seq = frame->seq;
    slot.t_sample_ns = frame->t_sample_ns;
    slot.t_published_ns = now_ns;
    slot.odom_mm = frame->odom_mm;
    slot.name = frame->name;
    slot.has_image = frame->bgr.size() == frame_size_ && frame->bgr.type() == CV_8UC3;
    if (closed.width() == slot.closed.width() && closed.height() == slot.closed.height())
        std::memcpy(slot.closed.row(0), closed.row(0),
                    static_cast<std::size_t>(closed.height()) * closed.words_per_row() * sizeof(std::uint64_t));
    else
        slot.closed.clear();
    // The plants found, not the whole fixed capacity (256 plants, 200 KB).
    slot.detections.status = detections.status;
    slot.detections.stats = detections.stats;
    slot.detections.plants.clear();
    for (const vision::Plant& p : detections.plants)
        slot.detections.plants.push_back(p);
    slot.has_class = has_class;
    if (has_class)
        std::copy_n(plant_class, detections.plants.size(), slot.plant_class.begin());
    frames_.publish();
    return given_back;
}

}  // namespace stemd::runtime
