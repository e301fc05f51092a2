#include "v4l2/v4l2_source.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <utility>

#include <opencv2/imgproc.hpp>
#include "stemd/base/clock.hpp"
#include "stemd/base/enum_names.hpp"

namespace stemd::drivers {

namespace {

constexpr base::EnumName<V4l2Source::State> kStates[]{
    {V4l2Source::State::closed, "closed"}, {V4l2Source::State::opening, "opening"},
    {V4l2Source::State::streaming, "streaming"}, {V4l2Source::State::failed, "failed"},
    {V4l2Source::State::backoff, "backoff"}};

// One row per pixel format: its option word, V4L2 fourcc and bytes per pixel.
struct PixelFormatRow {
    V4l2PixelFormat format;
    std::string_view name;
    std::uint32_t fourcc;
    int bytes_per_pixel;
};
constexpr PixelFormatRow kPixelFormats[]{
    {V4l2PixelFormat::yuyv, "yuyv", V4L2_PIX_FMT_YUYV, 2},
    {V4l2PixelFormat::bgr24, "bgr24", V4L2_PIX_FMT_BGR24, 3},
    {V4l2PixelFormat::grey, "grey", V4L2_PIX_FMT_GREY, 1},
};

const PixelFormatRow* row_of(V4l2PixelFormat format)
{
    for (const PixelFormatRow& r : kPixelFormats)
        if (r.format == format)
            return &r;
    return nullptr;
}

}  // namespace

std::optional<V4l2PixelFormat> parse_v4l2_pixel_format(std::string_view text)
{
    for (const PixelFormatRow& r : kPixelFormats)
        if (r.name == text)
            return r.format;
    return std::nullopt;
}

std::string_view to_string(V4l2PixelFormat format)
{
    const PixelFormatRow* r = row_of(format);
    return r ? r->name : "?";
}

std::uint32_t v4l2_fourcc_of(V4l2PixelFormat format)
{
    const PixelFormatRow* r = row_of(format);
    return r ? r->fourcc : 0;
}

int bytes_per_pixel(V4l2PixelFormat format)
{
    const PixelFormatRow* r = row_of(format);
    return r ? r->bytes_per_pixel : 0;
}

ConvertStatus convert_to_bgr(const std::uint8_t* data, std::size_t bytesused, std::size_t bytesperline,
                             cv::Size size, V4l2PixelFormat format, cv::Mat& bgr)
{
    if (bgr.size() != size || bgr.type() != CV_8UC3 || size.width <= 0 || size.height <= 0)
        return ConvertStatus::bad_size;
    const std::size_t row_bytes = static_cast<std::size_t>(size.width) * static_cast<std::size_t>(bytes_per_pixel(format));
    if (bytesperline < row_bytes || (format == V4l2PixelFormat::yuyv && size.width % 2 != 0))
        return ConvertStatus::bad_size;
    // The last row needs only its pixels, not the full stride.
    const std::size_t needed = bytesperline * static_cast<std::size_t>(size.height - 1) + row_bytes;
    if (data == nullptr || bytesused < needed)
        return ConvertStatus::corrupt;
    // Headers over the driver's buffer (no copy); cvtColor/copyTo into a
    // destination of the right size and type write into its buffer as is.
    auto* pixels = const_cast<std::uint8_t*>(data);
    switch (format) {
    case V4l2PixelFormat::yuyv:
        cv::cvtColor(cv::Mat(size, CV_8UC2, pixels, bytesperline), bgr, cv::COLOR_YUV2BGR_YUYV);
        break;
    case V4l2PixelFormat::bgr24:
        cv::Mat(size, CV_8UC3, pixels, bytesperline).copyTo(bgr);
        break;
    case V4l2PixelFormat::grey:
        cv::cvtColor(cv::Mat(size, CV_8UC1, pixels, bytesperline), bgr, cv::COLOR_GRAY2BGR);
        break;
    }
    return ConvertStatus::ok;
}

std::int64_t v4l2_capture_time_ns(const v4l2_buffer& buf, std::int64_t now_ns)
{
    if ((buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC)
        return now_ns;
    const std::int64_t stamped = static_cast<std::int64_t>(buf.timestamp.tv_sec) * 1'000'000'000 +
                                 static_cast<std::int64_t>(buf.timestamp.tv_usec) * 1'000;
    // Some drivers stamp the nominal frame time (vivid: stream start + n
    // frame periods), which can lie a little after the dequeue.
    return std::min(stamped, now_ns);
}

// --- V4l2Source ------------------------------------------------------------------

V4l2Source::V4l2Source(V4l2Options options, std::shared_ptr<spdlog::logger> log)
    : options_(std::move(options)),
      log_(std::move(log)),
      name_("v4l2:" + options_.device),
      backoff_(options_.backoff_initial, options_.backoff_max)
{
}

V4l2Source::~V4l2Source()
{
    stop();
}

std::int64_t V4l2Source::now_ns() const
{
    return options_.clock ? options_.clock() : base::monotonic_ns();
}

void V4l2Source::log_errno(const char* what, int err)
{
    SourceCounterCells::bump(counters_.errors);
    log_->error("{}: {}: {} (errno {})", options_.device, what, std::strerror(err), err);
}

bool V4l2Source::ioctl_retry(unsigned long request, void* arg) const
{
    int r = 0;
    do
        r = ::ioctl(fd_.get(), request, arg);
    while (r < 0 && errno == EINTR);
    return r == 0;
}

bool V4l2Source::open()
{
    if (state_ != State::closed) {
        log_->error("{}: open() in state {}", name_, base::name_of(kStates, state_));
        return false;
    }
    if (!open_device()) {
        close_device();
        state_ = State::failed;
        return false;
    }
    log_->info("{}: {}x{} {}, {} buffers, {}", name_, options_.size.width, options_.size.height,
               to_string(options_.pixel_format), buffers_.size(),
               granted_fps_ > 0 ? fmt::format("{:.2f} fps", granted_fps_) : std::string("driver's frame rate"));
    return true;
}

bool V4l2Source::open_device()
{
    state_ = State::opening;
    fd_.reset(::open(options_.device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC));
    if (!fd_.valid()) {
        log_errno("cannot open", errno);
        return false;
    }
    v4l2_capability cap{};
    if (!ioctl_retry(VIDIOC_QUERYCAP, &cap)) {
        log_errno("VIDIOC_QUERYCAP (not a V4L2 device?)", errno);
        return false;
    }
    const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0 || (caps & V4L2_CAP_STREAMING) == 0) {
        SourceCounterCells::bump(counters_.errors);
        log_->error("{}: {} ({}) is not a video capture device with streaming I/O", options_.device,
                    reinterpret_cast<const char*>(cap.card), reinterpret_cast<const char*>(cap.driver));
        return false;
    }

    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    fmt.fmt.pix.width = static_cast<std::uint32_t>(options_.size.width);
    fmt.fmt.pix.height = static_cast<std::uint32_t>(options_.size.height);
    fmt.fmt.pix.pixelformat = v4l2_fourcc_of(options_.pixel_format);
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (!ioctl_retry(VIDIOC_S_FMT, &fmt)) {
        log_errno("VIDIOC_S_FMT", errno);
        return false;
    }
    const v4l2_pix_format& pix = fmt.fmt.pix;
    if (static_cast<int>(pix.width) != options_.size.width || static_cast<int>(pix.height) != options_.size.height ||
        pix.pixelformat != v4l2_fourcc_of(options_.pixel_format)) {
        SourceCounterCells::bump(counters_.errors);
        const std::uint32_t f = pix.pixelformat;
        log_->error("{}: asked {}x{} {}, the driver offers {}x{} '{}{}{}{}'", options_.device, options_.size.width,
                    options_.size.height, to_string(options_.pixel_format), pix.width, pix.height,
                    static_cast<char>(f & 0xff), static_cast<char>((f >> 8) & 0xff),
                    static_cast<char>((f >> 16) & 0xff), static_cast<char>((f >> 24) & 0xff));
        return false;
    }
    bytesperline_ = pix.bytesperline;
    sizeimage_ = pix.sizeimage;

    granted_fps_ = 0;
    if (options_.fps > 0) {
        v4l2_streamparm parm{};
        parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        parm.parm.capture.timeperframe.numerator = 1000;
        parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(options_.fps * 1000));
        if (ioctl_retry(VIDIOC_S_PARM, &parm)) {
            const v4l2_fract& tpf = parm.parm.capture.timeperframe;
            if ((parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) && tpf.numerator > 0)
                granted_fps_ = static_cast<double>(tpf.denominator) / tpf.numerator;
        } else if (errno == EINVAL || errno == ENOTTY) {
            log_->info("{}: the device does not set a frame rate (VIDIOC_S_PARM: {}); using its own",
                       options_.device, std::strerror(errno));
        } else {
            log_errno("VIDIOC_S_PARM", errno);
            return false;
        }
    }

    v4l2_requestbuffers req{};
    req.count = options_.buffers;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    if (!ioctl_retry(VIDIOC_REQBUFS, &req)) {
        log_errno("VIDIOC_REQBUFS", errno);
        return false;
    }
    if (req.count < 2) {
        SourceCounterCells::bump(counters_.errors);
        log_->error("{}: the driver granted {} buffers, at least 2 are needed", options_.device, req.count);
        return false;
    }
    buffers_.reserve(req.count);
    for (std::uint32_t i = 0; i < req.count; ++i) {
        v4l2_buffer buf{};
        buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        buf.memory = V4L2_MEMORY_MMAP;
        buf.index = i;
        if (!ioctl_retry(VIDIOC_QUERYBUF, &buf)) {
            log_errno("VIDIOC_QUERYBUF", errno);
            return false;
        }
        void* data = ::mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_.get(), buf.m.offset);
        if (data == MAP_FAILED) {
            log_errno("mmap", errno);
            return false;
        }
        buffers_.emplace_back(data, buf.length);
    }
    return true;
}

bool V4l2Source::start_streaming()
{
    for (unsigned i = 0; i < buffers_.size(); ++i) {
        if (!requeue(i))
            return false;
    }
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (!ioctl_retry(VIDIOC_STREAMON, &type)) {
        log_errno("VIDIOC_STREAMON", errno);
        return false;
    }
    state_ = State::streaming;
    return true;
}

bool V4l2Source::start()
{
    if (state_ != State::opening) {
        log_->error("{}: start() in state {} (open() first)", name_, base::name_of(kStates, state_));
        return false;
    }
    if (!start_streaming()) {
        close_device();
        state_ = State::failed;
        return false;
    }
    return true;
}

bool V4l2Source::requeue(unsigned index)
{
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = index;
    if (!ioctl_retry(VIDIOC_QBUF, &buf)) {
        log_errno("VIDIOC_QBUF", errno);
        return false;
    }
    return true;
}

void V4l2Source::close_device()
{
    if (fd_.valid() && state_ == State::streaming) {
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        ioctl_retry(VIDIOC_STREAMOFF, &type);  // a vanished device fails here; closing is all that is left
    }
    buffers_.clear();  // unmaps
    fd_.reset();
    state_ = State::closed;
}

void V4l2Source::stop()
{
    close_device();
}

NextStatus V4l2Source::fail_and_backoff(const char* what, int err)
{
    log_errno(what, err);
    close_device();
    state_ = State::failed;
    backoff_.on_failure(now_ns());
    log_->warn("{}: reopening in {} ms", name_, (backoff_.next_attempt_ns() - now_ns()) / 1'000'000);
    state_ = State::backoff;
    return NextStatus::timeout;
}

NextStatus V4l2Source::next(Frame& into, std::chrono::nanoseconds timeout)
{
    if (state_ == State::backoff) {
        const std::int64_t now = now_ns();
        if (!backoff_.due(now)) {
            const std::int64_t wait = std::min<std::int64_t>(backoff_.wait_ns(now), timeout.count());
            base::sleep_for_ns(wait);
            if (!backoff_.due(now_ns())) {
                SourceCounterCells::bump(counters_.timeouts);
                return NextStatus::timeout;
            }
        }
        if (!open_device() || !start_streaming()) {
            close_device();
            state_ = State::failed;
            backoff_.on_failure(now_ns());
            log_->warn("{}: reopen failed; next attempt in {} ms", name_,
                       (backoff_.next_attempt_ns() - now_ns()) / 1'000'000);
            state_ = State::backoff;
            return NextStatus::timeout;
        }
        backoff_.on_success();
        SourceCounterCells::bump(counters_.reopens);
        log_->info("{}: reopened, streaming again", name_);
    }
    if (state_ != State::streaming)
        return NextStatus::failed;

    pollfd pfd{fd_.get(), POLLIN, 0};
    const int timeout_ms = static_cast<int>(std::chrono::ceil<std::chrono::milliseconds>(timeout).count());
    int ready = 0;
    do
        ready = ::poll(&pfd, 1, timeout_ms);
    while (ready < 0 && errno == EINTR);
    if (ready < 0)
        return fail_and_backoff("poll", errno);
    if (ready == 0) {
        SourceCounterCells::bump(counters_.timeouts);
        return NextStatus::timeout;
    }
    if (pfd.revents & (POLLERR | POLLHUP | POLLNVAL)) {
        // vb2 reports POLLERR when the device is gone or the queue broke.
        return fail_and_backoff("poll reported an error (device gone?)", pfd.revents & POLLNVAL ? EBADF : EIO);
    }

    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (!ioctl_retry(VIDIOC_DQBUF, &buf)) {
        if (errno == EAGAIN) {
            SourceCounterCells::bump(counters_.timeouts);
            return NextStatus::timeout;
        }
        return fail_and_backoff("VIDIOC_DQBUF", errno);
    }
    const std::int64_t dequeued_ns = now_ns();
    if (buf.index >= buffers_.size())
        return fail_and_backoff("VIDIOC_DQBUF returned an unknown buffer index", EINVAL);

    bool deliver = true;
    if ((buf.flags & V4L2_BUF_FLAG_ERROR) || buf.bytesused != sizeimage_ ||
        buf.bytesused > buffers_[buf.index].length()) {
        SourceCounterCells::bump(counters_.corrupt);
        skipped_log_.warn(*log_, dequeued_ns, "{}: frame {} corrupt (flags {:#x}, {} of {} bytes)", name_,
                          buf.sequence, buf.flags, buf.bytesused, sizeimage_);
        deliver = false;
    } else {
        const ConvertStatus converted = convert_to_bgr(buffers_[buf.index].bytes(), buf.bytesused, bytesperline_,
                                                       options_.size, options_.pixel_format, into.bgr);
        if (converted == ConvertStatus::bad_size) {
            SourceCounterCells::bump(counters_.bad_size);
            skipped_log_.wrong_size(*log_, dequeued_ns, name_, options_.size, into.bgr);
            deliver = false;
        } else if (converted == ConvertStatus::corrupt) {
            SourceCounterCells::bump(counters_.corrupt);
            deliver = false;
        }
    }
    if (!requeue(buf.index))
        return fail_and_backoff("re-queueing a buffer", errno);
    if (!deliver)
        return NextStatus::skipped;

    into.t_sample_ns = v4l2_capture_time_ns(buf, dequeued_ns);
    into.t_delivered_ns = dequeued_ns;
    into.t_recorded_ns = into.t_sample_ns;
    into.source_seq = buf.sequence;
    into.name.assign(name_);
    SourceCounterCells::bump(counters_.delivered);
    return NextStatus::frame;
}

SourceCounters V4l2Source::counters() const
{
    return counters_.load();
}

}  // namespace stemd::drivers
