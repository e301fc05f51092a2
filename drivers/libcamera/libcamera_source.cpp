#include "libcamera/libcamera_source.hpp"

#include <poll.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <libcamera/libcamera.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "stemd/runtime/spsc_ring.hpp"

namespace stemd::drivers {

namespace {

std::int64_t monotonic_now_ns()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

const char* state_name(LibcameraSource::State s)
{
    switch (s) {
    case LibcameraSource::State::closed: return "closed";
    case LibcameraSource::State::opened: return "opened";
    case LibcameraSource::State::streaming: return "streaming";
    case LibcameraSource::State::failed: return "failed";
    }
    return "?";
}

// libcamera returns -errno.
std::string errno_text(int r)
{
    const int e = r < 0 ? -r : r;
    return fmt::format("{} (errno {})", std::strerror(e), e);
}

bool all_digits(std::string_view s)
{
    return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::string list_ids(const std::vector<std::string>& ids)
{
    if (ids.empty())
        return "none";
    std::string out;
    for (std::size_t i = 0; i < ids.size(); ++i)
        out += fmt::format("{}[{}] '{}'", i ? ", " : "", i, ids[i]);
    return out;
}

}  // namespace

PlaneStatus copy_plane_to_bgr(const std::uint8_t* data, std::size_t bytesused, std::size_t stride, cv::Size size,
                              LibcameraByteOrder order, cv::Mat& bgr)
{
    if (bgr.size() != size || bgr.type() != CV_8UC3 || size.width <= 0 || size.height <= 0)
        return PlaneStatus::bad_size;
    const std::size_t row_bytes = static_cast<std::size_t>(size.width) * 3;
    if (stride < row_bytes)
        return PlaneStatus::bad_size;
    // The last row needs only its pixels, not the full stride.
    const std::size_t needed = stride * static_cast<std::size_t>(size.height - 1) + row_bytes;
    if (data == nullptr || bytesused < needed)
        return PlaneStatus::corrupt;
    // A header over the mapped plane (no copy); copyTo/cvtColor into a
    // destination of the right size and type write into its buffer as is.
    const cv::Mat plane(size, CV_8UC3, const_cast<std::uint8_t*>(data), stride);
    if (order == LibcameraByteOrder::bgr)
        plane.copyTo(bgr);
    else
        cv::cvtColor(plane, bgr, cv::COLOR_RGB2BGR);
    return PlaneStatus::ok;
}

std::optional<std::size_t> select_camera(const std::vector<std::string>& ids, std::string_view wanted,
                                         std::string& why)
{
    if (all_digits(wanted)) {
        std::size_t index = 0;
        for (char c : wanted)
            index = std::min<std::size_t>(index * 10 + static_cast<std::size_t>(c - '0'), 1'000'000);
        if (index < ids.size())
            return index;
        why = fmt::format("no camera with index {} (cameras: {})", wanted, list_ids(ids));
        return std::nullopt;
    }
    for (std::size_t i = 0; i < ids.size(); ++i) {
        if (ids[i] == wanted)
            return i;
    }
    std::optional<std::size_t> found;
    std::vector<std::string> matching;
    for (std::size_t i = 0; i < ids.size(); ++i) {
        if (!wanted.empty() && ids[i].find(wanted) != std::string::npos) {
            found = i;
            matching.push_back(ids[i]);
        }
    }
    if (matching.size() == 1)
        return found;
    if (matching.empty())
        why = fmt::format("no camera matches '{}' (cameras: {})", wanted, list_ids(ids));
    else
        why = fmt::format("'{}' matches several cameras ({}); give the full id", wanted, list_ids(matching));
    return std::nullopt;
}

std::int64_t libcamera_capture_time_ns(std::optional<std::int64_t> sensor_timestamp_ns, std::int64_t now_ns)
{
    if (!sensor_timestamp_ns || *sensor_timestamp_ns <= 0)
        return now_ns;
    return std::min(*sensor_timestamp_ns, now_ns);
}

// --- the libcamera objects -------------------------------------------------------

struct LibcameraSource::Impl {
    // Stops the manager on every path (the camera must be released first).
    struct ManagerStopper {
        void operator()(libcamera::CameraManager* cm) const
        {
            cm->stop();
            delete cm;
        }
    };

    // One mmapped plane of a frame buffer, unmapped exactly once.
    class MappedPlane {
    public:
        MappedPlane(void* map, std::size_t map_length, std::size_t offset)
            : map_(map), map_length_(map_length), offset_(offset)
        {
        }
        MappedPlane(MappedPlane&& other) noexcept
            : map_(std::exchange(other.map_, MAP_FAILED)), map_length_(other.map_length_), offset_(other.offset_)
        {
        }
        MappedPlane& operator=(MappedPlane&&) = delete;
        MappedPlane(const MappedPlane&) = delete;
        MappedPlane& operator=(const MappedPlane&) = delete;
        ~MappedPlane()
        {
            if (map_ != MAP_FAILED)
                ::munmap(map_, map_length_);
        }
        const std::uint8_t* bytes() const { return static_cast<const std::uint8_t*>(map_) + offset_; }
        std::size_t length() const { return map_length_ - offset_; }

    private:
        void* map_;
        std::size_t map_length_;
        std::size_t offset_;
    };

    // libcamera's thread: hand the request's index over, wake next(). No
    // locks, no allocation, no logging here.
    void completed(libcamera::Request* request)
    {
        if (!ring->try_push(request->cookie()))
            ring_full.fetch_add(1, std::memory_order_relaxed);
        wake();
    }
    void unplugged()
    {
        disconnected.store(true, std::memory_order_release);
        wake();
    }
    void wake() const
    {
        const std::uint64_t one = 1;
        [[maybe_unused]] const ssize_t n = ::write(event_fd, &one, sizeof one);  // only fails if the counter is saturated
    }

    ~Impl()
    {
        if (event_fd >= 0)
            ::close(event_fd);
    }

    std::unique_ptr<libcamera::CameraManager, ManagerStopper> manager;
    std::shared_ptr<libcamera::Camera> camera;
    bool acquired = false;
    bool started = false;
    bool connected = false;  // our slots are connected to the camera's signals
    std::unique_ptr<libcamera::CameraConfiguration> config;
    libcamera::Stream* stream = nullptr;
    std::size_t stride = 0;
    std::unique_ptr<libcamera::FrameBufferAllocator> allocator;
    std::vector<std::unique_ptr<libcamera::Request>> requests;  // index = cookie
    std::vector<MappedPlane> planes;                           // index = cookie
    std::unique_ptr<runtime::SpscRing<std::uint64_t>> ring;
    int event_fd = -1;
    std::atomic<bool> disconnected{false};
    std::atomic<std::uint64_t> ring_full{0};
};

// --- LibcameraSource -------------------------------------------------------------

LibcameraSource::LibcameraSource(LibcameraOptions options, std::shared_ptr<spdlog::logger> log)
    : options_(std::move(options)), log_(std::move(log)), name_("libcamera:" + options_.camera)
{
}

LibcameraSource::~LibcameraSource()
{
    stop();
}

std::size_t LibcameraSource::buffer_count() const
{
    return impl_ ? impl_->requests.size() : 0;
}

bool LibcameraSource::open()
{
    if (state_ != State::closed) {
        log_->error("{}: open() in state {}", name_, state_name(state_));
        return false;
    }
    if (!open_camera()) {
        close_camera();
        state_ = State::failed;
        return false;
    }
    state_ = State::opened;
    log_->info("{}: {}x{} {}, stride {}, {} buffers", name_, options_.size.width, options_.size.height,
               order_ == LibcameraByteOrder::bgr ? "RGB888 (B,G,R bytes)" : "BGR888 (R,G,B bytes)", impl_->stride,
               impl_->requests.size());
    return true;
}

bool LibcameraSource::open_camera()
{
    impl_ = std::make_unique<Impl>();
    Impl& m = *impl_;
    const auto error = [this](const std::string& what) {
        errors_.fetch_add(1, std::memory_order_relaxed);
        log_->error("{}: {}", name_, what);
        return false;
    };

    {
        auto manager = std::make_unique<libcamera::CameraManager>();
        if (const int r = manager->start(); r < 0)
            return error("CameraManager::start: " + errno_text(r));
        m.manager.reset(manager.release());
    }
    const auto cameras = m.manager->cameras();
    std::vector<std::string> ids;
    ids.reserve(cameras.size());
    for (const auto& c : cameras)
        ids.push_back(c->id());
    std::string why;
    const auto index = select_camera(ids, options_.camera, why);
    if (!index)
        return error("source.libcamera_camera: " + why);
    m.camera = cameras[*index];
    camera_id_ = m.camera->id();
    name_ = "libcamera:" + camera_id_;

    if (const int r = m.camera->acquire(); r < 0)
        return error("cannot acquire the camera (in use by another process?): " + errno_text(r));
    m.acquired = true;

    m.config = m.camera->generateConfiguration({libcamera::StreamRole::Viewfinder});
    if (!m.config || m.config->size() != 1)
        return error("no viewfinder stream configuration");
    libcamera::StreamConfiguration& sc = m.config->at(0);
    sc.pixelFormat = libcamera::formats::RGB888;
    sc.size = libcamera::Size(static_cast<unsigned>(options_.size.width), static_cast<unsigned>(options_.size.height));
    if (m.config->validate() == libcamera::CameraConfiguration::Invalid)
        return error("configuration " + sc.toString() + " is invalid");
    if (sc.pixelFormat == libcamera::formats::RGB888)
        order_ = LibcameraByteOrder::bgr;
    else if (sc.pixelFormat == libcamera::formats::BGR888)
        order_ = LibcameraByteOrder::rgb;
    else
        return error(fmt::format("asked RGB888, the camera offers {}", sc.pixelFormat.toString()));
    if (static_cast<int>(sc.size.width) != options_.size.width ||
        static_cast<int>(sc.size.height) != options_.size.height)
        return error(fmt::format("asked {}x{}, the camera offers {}", options_.size.width, options_.size.height,
                                 sc.size.toString()));
    if (const int r = m.camera->configure(m.config.get()); r < 0)
        return error("configure " + sc.toString() + ": " + errno_text(r));
    m.stream = sc.stream();
    m.stride = sc.stride != 0 ? sc.stride : static_cast<std::size_t>(options_.size.width) * 3;

    m.allocator = std::make_unique<libcamera::FrameBufferAllocator>(m.camera);
    if (const int r = m.allocator->allocate(m.stream); r < 0)
        return error("FrameBufferAllocator::allocate: " + errno_text(r));
    const auto& buffers = m.allocator->buffers(m.stream);
    if (buffers.size() < 2)
        return error(fmt::format("{} buffers allocated, at least 2 are needed", buffers.size()));
    m.requests.reserve(buffers.size());
    m.planes.reserve(buffers.size());
    for (std::size_t i = 0; i < buffers.size(); ++i) {
        libcamera::FrameBuffer* buffer = buffers[i].get();
        if (buffer->planes().size() != 1)
            return error(fmt::format("buffer has {} planes, a packed RGB format has 1", buffer->planes().size()));
        const libcamera::FrameBuffer::Plane& plane = buffer->planes().front();
        const std::size_t map_length = static_cast<std::size_t>(plane.offset) + plane.length;
        void* map = ::mmap(nullptr, map_length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
        if (map == MAP_FAILED)
            return error("mmap of a frame buffer: " + errno_text(errno));
        m.planes.emplace_back(map, map_length, plane.offset);
        auto request = m.camera->createRequest(i);  // cookie = index
        if (!request)
            return error("createRequest failed");
        if (const int r = request->addBuffer(m.stream, buffer); r < 0)
            return error("Request::addBuffer: " + errno_text(r));
        m.requests.push_back(std::move(request));
    }
    // Every request is in at most one place (camera, ring, next()): the ring
    // never overflows.
    m.ring = std::make_unique<runtime::SpscRing<std::uint64_t>>(m.requests.size());
    m.event_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (m.event_fd < 0)
        return error("eventfd: " + errno_text(errno));
    m.camera->requestCompleted.connect(&m, &Impl::completed);
    m.camera->disconnected.connect(&m, &Impl::unplugged);
    m.connected = true;
    return true;
}

bool LibcameraSource::start()
{
    if (state_ != State::opened) {
        log_->error("{}: start() in state {} (open() first)", name_, state_name(state_));
        return false;
    }
    Impl& m = *impl_;
    libcamera::ControlList controls(libcamera::controls::controls);
    const bool set_rate =
        options_.fps > 0 && m.camera->controls().find(&libcamera::controls::FrameDurationLimits) !=
                                m.camera->controls().end();
    if (set_rate) {
        const auto frame_us = static_cast<std::int64_t>(std::lround(1e6 / options_.fps));
        const std::array<std::int64_t, 2> limits{frame_us, frame_us};
        controls.set(libcamera::controls::FrameDurationLimits, libcamera::Span<const std::int64_t, 2>(limits));
    }
    int r = m.camera->start(set_rate ? &controls : nullptr);
    if (r < 0) {
        errors_.fetch_add(1, std::memory_order_relaxed);
        log_->error("{}: Camera::start: {}", name_, errno_text(r));
        close_camera();
        state_ = State::failed;
        return false;
    }
    m.started = true;
    if (!set_rate && options_.fps > 0)
        log_->info("{}: the camera does not set a frame rate (no FrameDurationLimits); using its own", name_);
    for (auto& request : m.requests) {
        if ((r = m.camera->queueRequest(request.get())) < 0) {
            errors_.fetch_add(1, std::memory_order_relaxed);
            log_->error("{}: Camera::queueRequest: {}", name_, errno_text(r));
            close_camera();
            state_ = State::failed;
            return false;
        }
    }
    state_ = State::streaming;
    return true;
}

void LibcameraSource::close_camera()
{
    if (!impl_)
        return;
    Impl& m = *impl_;
    if (m.started)
        m.camera->stop();  // completes (cancels) every queued request first
    m.started = false;
    if (m.connected) {
        m.camera->requestCompleted.disconnect(&m, &Impl::completed);
        m.camera->disconnected.disconnect(&m, &Impl::unplugged);
    }
    m.requests.clear();
    m.planes.clear();      // unmaps
    m.allocator.reset();   // frees the buffers
    m.config.reset();
    if (m.acquired)
        m.camera->release();
    m.camera.reset();
    m.manager.reset();     // stops the manager, after the camera is gone
    impl_.reset();
}

void LibcameraSource::stop()
{
    close_camera();
    state_ = State::closed;
}

NextStatus LibcameraSource::fail(const std::string& what)
{
    errors_.fetch_add(1, std::memory_order_relaxed);
    log_->error("{}: {}; the source stops", name_, what);
    state_ = State::failed;
    return NextStatus::failed;
}

NextStatus LibcameraSource::next(Frame& into, std::chrono::nanoseconds timeout)
{
    if (state_ != State::streaming)
        return NextStatus::failed;
    Impl& m = *impl_;
    const std::int64_t deadline = monotonic_now_ns() + timeout.count();
    std::uint64_t index = 0;
    while (!m.ring->try_pop(index)) {
        if (m.disconnected.load(std::memory_order_acquire))
            return fail("the camera was disconnected");
        const std::int64_t left = deadline - monotonic_now_ns();
        if (left <= 0) {
            timeouts_.fetch_add(1, std::memory_order_relaxed);
            return NextStatus::timeout;
        }
        pollfd pfd{m.event_fd, POLLIN, 0};
        const int r = ::poll(&pfd, 1, static_cast<int>((left + 999'999) / 1'000'000));
        if (r < 0 && errno != EINTR)
            return fail("poll on the completion eventfd: " + errno_text(errno));
        if (r > 0) {
            std::uint64_t count = 0;
            [[maybe_unused]] const ssize_t n = ::read(m.event_fd, &count, sizeof count);  // EAGAIN: already drained
        }
    }
    const std::int64_t dequeued_ns = monotonic_now_ns();
    if (index >= m.requests.size())
        return fail(fmt::format("completed request has an unknown index {}", index));
    libcamera::Request* request = m.requests[index].get();
    libcamera::FrameBuffer* buffer = request->findBuffer(m.stream);

    bool deliver = true;
    const libcamera::FrameMetadata* meta = buffer ? &buffer->metadata() : nullptr;
    const std::size_t bytesused =
        meta && !meta->planes().empty() ? meta->planes()[0].bytesused : 0;
    if (request->status() != libcamera::Request::RequestComplete || meta == nullptr ||
        meta->status != libcamera::FrameMetadata::FrameSuccess) {
        corrupt_.fetch_add(1, std::memory_order_relaxed);
        log_->warn("{}: request {} {} (frame status {}); skipped", name_, index,
                   request->status() == libcamera::Request::RequestCancelled ? "cancelled" : "not complete",
                   meta ? static_cast<int>(meta->status) : -1);
        deliver = false;
    } else {
        const PlaneStatus copied =
            copy_plane_to_bgr(m.planes[index].bytes(), std::min(bytesused, m.planes[index].length()), m.stride,
                              options_.size, order_, into.bgr);
        if (copied == PlaneStatus::bad_size) {
            bad_size_.fetch_add(1, std::memory_order_relaxed);
            log_->warn("{}: frame is {}x{}, the slot is {}x{} type {}; skipped", name_, options_.size.width,
                       options_.size.height, into.bgr.cols, into.bgr.rows, into.bgr.type());
            deliver = false;
        } else if (copied == PlaneStatus::corrupt) {
            corrupt_.fetch_add(1, std::memory_order_relaxed);
            log_->warn("{}: frame {} has {} bytes, {}x{} at stride {} needs more; skipped", name_, meta->sequence,
                       bytesused, options_.size.width, options_.size.height, m.stride);
            deliver = false;
        }
    }
    const std::optional<std::int64_t> sensor_ns = request->metadata().get(libcamera::controls::SensorTimestamp);
    const std::uint64_t sequence = meta ? meta->sequence : 0;

    request->reuse(libcamera::Request::ReuseBuffers);
    if (const int r = m.camera->queueRequest(request); r < 0)
        return fail("Camera::queueRequest: " + errno_text(r));
    if (!deliver)
        return NextStatus::skipped;

    if (!sensor_ns)
        unstamped_.fetch_add(1, std::memory_order_relaxed);
    into.t_capture_ns = libcamera_capture_time_ns(sensor_ns, dequeued_ns);
    into.t_recorded_ns = into.t_capture_ns;
    into.source_seq = sequence;
    into.name.assign(name_);
    frames_.fetch_add(1, std::memory_order_relaxed);
    return NextStatus::frame;
}

SourceCounters LibcameraSource::counters() const
{
    return {.delivered = frames_.load(std::memory_order_relaxed),
            .corrupt = corrupt_.load(std::memory_order_relaxed),
            .bad_size = bad_size_.load(std::memory_order_relaxed),
            .loops = 0};
}

LibcameraCounters LibcameraSource::libcamera_counters() const
{
    return {.frames = frames_.load(std::memory_order_relaxed),
            .timeouts = timeouts_.load(std::memory_order_relaxed),
            .errors = errors_.load(std::memory_order_relaxed),
            .corrupt = corrupt_.load(std::memory_order_relaxed),
            .bad_size = bad_size_.load(std::memory_order_relaxed),
            .unstamped = unstamped_.load(std::memory_order_relaxed)};
}

}  // namespace stemd::drivers
