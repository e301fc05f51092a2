#include "replay/replay_source.hpp"

#include <cmath>
#include <limits>
#include <system_error>

#include <opencv2/imgcodecs.hpp>

#include "stemd/io/recording.hpp"
#include "stemd/base/clock.hpp"

namespace stemd::drivers {

namespace {

// IGNORE_ORIENTATION: frames are stored as the camera delivered them; an
// EXIF rotation must not turn them (nor change their size).
constexpr int kColorFlags = cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION;
constexpr int kGreyFlags = cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION;

// Copies `from` into `plane` without reallocating it; false if they differ.
bool copy_into(const cv::Mat& from, cv::Mat& plane)
{
    if (from.size() != plane.size() || from.type() != plane.type())
        return false;
    from.copyTo(plane);
    return true;
}

}  // namespace

ReplaySource::ReplaySource(ReplayOptions options, std::shared_ptr<spdlog::logger> log)
    : options_(std::move(options)), log_(std::move(log)), name_("replay:" + options_.dir.string())
{
}

ReplaySource::~ReplaySource()
{
    stop();
}

bool ReplaySource::open()
{
    if (state_ != State::closed) {
        log_->error("{}: open() in state {}", name_, static_cast<int>(state_));
        return false;
    }
    if (!read_frames_csv() || (options_.preload && !preload_all())) {
        state_ = State::failed;
        return false;
    }
    const Entry& first = entries_.front();
    const Entry& last = entries_.back();
    const std::int64_t span_ns = last.t_ns - first.t_ns;
    const std::int64_t n = static_cast<std::int64_t>(entries_.size());
    // A looping pass lasts the recording plus one mean frame interval, so
    // the first frame of the next pass keeps the recording's rhythm.
    loop_period_ns_ = n > 1 ? span_ns + span_ns / (n - 1) : 100'000'000;
    // The same for the odometer, over the frames that have one (the reader
    // has checked it never decreases).
    const Entry* first_odom = nullptr;
    const Entry* last_odom = nullptr;
    std::int64_t odom_frames = 0;
    for (const Entry& entry : entries_) {
        if (!std::isfinite(entry.odom_mm))
            continue;
        first_odom = first_odom ? first_odom : &entry;
        last_odom = &entry;
        ++odom_frames;
    }
    const double odom_span_mm = odom_frames > 1 ? last_odom->odom_mm - first_odom->odom_mm : 0.0;
    loop_odom_period_mm_ =
        odom_frames > 1 ? odom_span_mm + odom_span_mm / static_cast<double>(odom_frames - 1) : 0.0;
    state_ = State::opened;
    log_->info("{}: {} frames over {:.2f} s, pacing {}, {}{}", name_, entries_.size(), span_ns / 1e9,
               options_.pacing == ReplayOptions::Pacing::recorded ? "recorded t_ns" : "fast",
               options_.loop ? "looping" : "once", options_.preload ? ", preloaded" : "");
    return true;
}

bool ReplaySource::read_frames_csv()
{
    // The tools' reader and rules (header, t_ns increasing with bounded
    // gaps, odometer): the pacing arithmetic below relies on them.
    std::string error;
    const auto recording = io::read_recording(options_.dir, error);
    if (!recording) {
        log_->error("{}: {}", name_, error);
        return false;
    }
    if (recording->frames.empty()) {
        log_->error("{}: no frames", (options_.dir / "frames.csv").string());
        return false;
    }
    auto resolve = [&](const std::string& relative) {
        return relative.empty() ? std::filesystem::path{} : recording->resolve(relative);
    };
    entries_.reserve(recording->frames.size());
    for (const io::RecordingFrame& frame : recording->frames) {
        Entry entry;
        entry.t_ns = frame.t_ns;
        entry.rgb = resolve(frame.rgb);
        entry.nir = resolve(frame.nir);
        entry.mask = resolve(frame.mask);
        entry.plant_class = resolve(frame.plant_class);
        entry.odom_mm = frame.odom_mm.value_or(std::numeric_limits<double>::quiet_NaN());
        entry.name = !frame.rgb.empty() ? frame.rgb : frame.mask;
        entries_.push_back(std::move(entry));
    }
    return true;
}

bool ReplaySource::preload_all()
{
    // Every plane a recording has is decoded, since which ones the pipeline
    // uses is the frame's business; a corrupt one marks its frame.
    log_->info("{}: preloading {} frames", name_, entries_.size());
    for (Entry& entry : entries_) {
        if (options_.cancelled && options_.cancelled()) {
            log_->info("{}: preload cancelled", name_);
            return false;
        }
        entry.preload_fault = Entry::Fault::none;
        auto load = [&](const std::filesystem::path& path, int flags, cv::Mat& out) {
            if (path.empty())
                return true;
            if (!read_file(path)) {
                entry.preload_fault = Entry::Fault::corrupt;
                return false;
            }
            if (!header_fits(path, options_.frame_size, false, &entry.preload_fault))
                return false;
            entry.preload_fault = Entry::Fault::corrupt;
            try {
                out = cv::imdecode(file_buffer_, flags);
            } catch (const cv::Exception& e) {
                log_->warn("{}: cannot decode: {}", path.string(), e.what());
                return false;
            }
            if (out.empty()) {
                log_->warn("{}: cannot decode (corrupt or not an image); it will be skipped", path.string());
                return false;
            }
            entry.preload_fault = Entry::Fault::none;
            return true;
        };
        load(entry.rgb, kColorFlags, entry.bgr_data) && load(entry.nir, kGreyFlags, entry.nir_data) &&
            load(entry.mask, kGreyFlags, entry.mask_data) && load(entry.plant_class, kGreyFlags, entry.class_data);
    }
    return true;
}

bool ReplaySource::start()
{
    if (state_ != State::opened) {
        log_->error("{}: start() before open()", name_);
        return false;
    }
    index_ = 0;
    loop_offset_ns_ = 0;
    loop_odom_offset_mm_ = 0;
    start_mono_ns_ = base::monotonic_ns();
    state_ = State::streaming;
    return true;
}

void ReplaySource::stop()
{
    if (state_ == State::streaming)
        state_ = State::ended;
}

std::int64_t ReplaySource::due_ns(const Entry& entry) const
{
    return start_mono_ns_ + loop_offset_ns_ + (entry.t_ns - entries_.front().t_ns);
}

void ReplaySource::set_next_odometer(Frame& into) const
{
    // index_ is the entry after the one just delivered. Fast pacing has no
    // time to put the next sample at.
    into.t_next_ns = 0;
    into.odom_next_mm = std::numeric_limits<double>::quiet_NaN();
    if (options_.pacing != ReplayOptions::Pacing::recorded)
        return;
    if (index_ < entries_.size()) {
        into.t_next_ns = due_ns(entries_[index_]);
        into.odom_next_mm = entries_[index_].odom_mm + loop_odom_offset_mm_;
    } else if (options_.loop) {
        into.t_next_ns = due_ns(entries_.front()) + loop_period_ns_;
        into.odom_next_mm = entries_.front().odom_mm + loop_odom_offset_mm_ + loop_odom_period_mm_;
    } else if (entries_.size() >= 2) {
        // Played once: past its end the machine is taken to drive on at its
        // last frame step (what the actuator assumes at the end of a
        // stream), so the last frame's plants are scheduled like the others.
        const Entry& a = entries_[entries_.size() - 2];
        const Entry& b = entries_.back();
        into.t_next_ns = due_ns(b) + (b.t_ns - a.t_ns);
        into.odom_next_mm = b.odom_mm + (b.odom_mm - a.odom_mm) + loop_odom_offset_mm_;
    }
}

NextStatus ReplaySource::next(Frame& into, std::chrono::nanoseconds timeout)
{
    if (state_ == State::ended)
        return NextStatus::end_of_stream;
    if (state_ != State::streaming)
        return NextStatus::failed;
    if (index_ == entries_.size()) {
        if (!options_.loop) {
            state_ = State::ended;
            log_->info("{}: end of recording", name_);
            return NextStatus::end_of_stream;
        }
        index_ = 0;
        loop_offset_ns_ += loop_period_ns_;
        loop_odom_offset_mm_ += loop_odom_period_mm_;
        loops_.fetch_add(1, std::memory_order_relaxed);
    }
    const Entry& entry = entries_[index_];
    if (options_.pacing == ReplayOptions::Pacing::recorded) {
        const std::int64_t t_due_ns = due_ns(entry);
        const std::int64_t now = base::monotonic_ns();
        if (t_due_ns - now > timeout.count()) {
            base::sleep_until_ns(now + timeout.count());
            return NextStatus::timeout;
        }
        if (t_due_ns > now) {
            base::sleep_until_ns(t_due_ns);
        } else {
            const std::int64_t lateness_ns = now - t_due_ns;
            if (lateness_ns > SourceCounters::kLateToleranceNs) {
                late_.fetch_add(1, std::memory_order_relaxed);
                // The recording's clock slips by the lateness: the frames
                // after this one keep their recorded spacing from it (the
                // machine waited) rather than come in a burst, and the next
                // frame's odometer sample stays ahead of this one.
                start_mono_ns_ += lateness_ns;
            }
            // One writer (this thread): load-compare-store is enough.
            if (lateness_ns > worst_lateness_ns_.load(std::memory_order_relaxed))
                worst_lateness_ns_.store(lateness_ns, std::memory_order_relaxed);
        }
    }
    ++index_;
    if (!fill(entry, into))
        return NextStatus::skipped;
    into.odom_mm = entry.odom_mm + loop_odom_offset_mm_;
    into.t_delivered_ns = base::monotonic_ns();
    into.t_sample_ns = into.t_delivered_ns;
    set_next_odometer(into);
    into.t_recorded_ns = entry.t_ns;
    into.source_seq = SourceCounterCells::bump(counters_.delivered);
    into.name.assign(entry.name);
    return NextStatus::frame;
}

bool ReplaySource::fill(const Entry& entry, Frame& into)
{
    struct Plane {
        const std::filesystem::path& path;
        const cv::Mat& preloaded;
        int flags;
        cv::Mat& plane;
    };
    const Plane planes[] = {{entry.rgb, entry.bgr_data, kColorFlags, into.bgr},
                            {entry.nir, entry.nir_data, kGreyFlags, into.nir},
                            {entry.mask, entry.mask_data, kGreyFlags, into.mask}};
    into.has_class_map = false;
    if (options_.preload && entry.preload_fault != Entry::Fault::none) {
        SourceCounterCells::bump(entry.preload_fault == Entry::Fault::bad_size ? counters_.bad_size : counters_.corrupt);
        return false;
    }
    auto fill_plane = [&](const Plane& p) {
        if (!options_.preload)
            return decode_into(p.path, p.flags, p.plane);
        if (copy_into(p.preloaded, p.plane))
            return true;
        log_->warn("{}: {} is {}x{} type {}, the slots are {}x{} type {}; skipped", name_, p.path.string(),
                   p.preloaded.cols, p.preloaded.rows, p.preloaded.type(), p.plane.cols, p.plane.rows,
                   p.plane.type());
        SourceCounterCells::bump(counters_.bad_size);
        return false;
    };
    for (const Plane& p : planes) {
        if (p.plane.empty())
            continue;  // the pipeline does not use this plane
        if (p.path.empty()) {
            log_->warn("{}: frame {} has no image for a plane the pipeline needs; skipped", name_, entry.name);
            SourceCounterCells::bump(counters_.corrupt);
            return false;
        }
        if (!fill_plane(p))
            return false;
    }
    // The class map is optional: filled when both the slot and the frame
    // have one, and then checked like the other planes.
    if (!into.plant_class.empty() && !entry.plant_class.empty()) {
        if (!fill_plane({entry.plant_class, entry.class_data, kGreyFlags, into.plant_class}))
            return false;
        into.has_class_map = true;
    }
    return true;
}

bool ReplaySource::read_file(const std::filesystem::path& path)
{
    std::string why;
    if (io::read_whole_file(path, io::kMaxImageFileBytes, file_buffer_, why))
        return true;
    log_->warn("{}: {}; skipped", path.string(), why);
    return false;
}

bool ReplaySource::header_fits(const std::filesystem::path& path, cv::Size expected, bool count, Entry::Fault* fault)
{
    // Before decoding: a small file may declare a huge image, which the
    // decoder would allocate in full only to be refused afterwards.
    std::string why;
    const io::HeaderCheck check = io::check_image_header(file_buffer_, expected, why);
    if (check == io::HeaderCheck::ok)
        return true;
    const bool bad_size = check == io::HeaderCheck::bad_size;
    if (bad_size)
        log_->warn("{}: {}; skipped, not decoded", path.string(), why);
    else
        log_->warn("{}: cannot decode: {}; skipped", path.string(), why);
    if (count)
        SourceCounterCells::bump(bad_size ? counters_.bad_size : counters_.corrupt);
    if (fault != nullptr)
        *fault = bad_size ? Entry::Fault::bad_size : Entry::Fault::corrupt;
    return false;
}

bool ReplaySource::decode_into(const std::filesystem::path& path, int imread_flags, cv::Mat& plane)
{
    if (!read_file(path)) {
        SourceCounterCells::bump(counters_.corrupt);
        return false;
    }
    if (!header_fits(path, plane.size(), true, nullptr))
        return false;
    // Decoded into a fresh Mat, then copied into the slot. Decoding straight
    // into the slot (imdecode's `dst`) cannot be told apart from a failure in
    // OpenCV 4.6: with no decoder or a bad header it returns `dst` untouched,
    // which would deliver the slot's previous pixels as a new frame.
    cv::Mat decoded;
    try {
        decoded = cv::imdecode(file_buffer_, imread_flags);
    } catch (const cv::Exception& e) {
        log_->warn("{}: cannot decode: {}; skipped", path.string(), e.what());
        SourceCounterCells::bump(counters_.corrupt);
        return false;
    }
    if (decoded.empty()) {
        log_->warn("{}: cannot decode (corrupt or not an image); skipped", path.string());
        SourceCounterCells::bump(counters_.corrupt);
        return false;
    }
    if (!copy_into(decoded, plane)) {
        log_->warn("{}: is {}x{} type {}, the slots are {}x{} type {}; skipped", path.string(), decoded.cols,
                   decoded.rows, decoded.type(), plane.cols, plane.rows, plane.type());
        SourceCounterCells::bump(counters_.bad_size);
        return false;
    }
    return true;
}

SourceCounters ReplaySource::counters() const
{
    SourceCounters c = counters_.load();
    c.loops = loops_.load(std::memory_order_relaxed);
    c.late = late_.load(std::memory_order_relaxed);
    c.worst_lateness_ms = static_cast<double>(worst_lateness_ns_.load(std::memory_order_relaxed)) / 1e6;
    return c;
}

}  // namespace stemd::drivers
