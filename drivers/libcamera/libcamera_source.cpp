#include "libcamera/libcamera_source.hpp"

#include <dirent.h>
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
#include <cstdlib>
#include <cstring>
#include <string_view>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "stemd/base/spsc_ring.hpp"
#include "stemd/base/clock.hpp"
#include "stemd/base/enum_names.hpp"
#include "stemd/base/unique_fd.hpp"
#include "stemd/base/mapped_memory.hpp"

namespace stemd::drivers {

namespace {


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

// True if a V4L2 or media-controller node this process has open (libcamera's
// own fds) was unregistered: the kernel then reports POLLHUP on it (v4l2_poll,
// media_poll), which a live node never does. libcamera 0.0.3 cannot stop a
// camera whose nodes are gone (stopping fails, requests stay queued and
// PipelineHandler::stop() aborts on an assertion), so the caller skips
// Camera::stop() and release() then.
constexpr std::int64_t kDrainNs = 1'000'000'000;

bool media_nodes_unregistered()
{
    DIR* dir = ::opendir("/proc/self/fd");
    if (dir == nullptr)
        return false;
    bool gone = false;
    while (const dirent* e = ::readdir(dir)) {
        if (e->d_name[0] == '.')
            continue;
        char target[256];
        const std::string link = std::string("/proc/self/fd/") + e->d_name;
        const ssize_t n = ::readlink(link.c_str(), target, sizeof target - 1);
        if (n <= 0)
            continue;
        const std::string_view t(target, static_cast<std::size_t>(n));
        if (!t.starts_with("/dev/video") && !t.starts_with("/dev/media") && !t.starts_with("/dev/v4l-subdev"))
            continue;
        pollfd pfd{std::atoi(e->d_name), POLLIN, 0};
        if (::poll(&pfd, 1, 0) > 0 && (pfd.revents & POLLHUP) != 0) {
            gone = true;
            break;
        }
    }
    ::closedir(dir);
    return gone;
}

}  // namespace

namespace {

constexpr base::EnumName<LibcameraSource::State> kStates[]{
    {LibcameraSource::State::closed, "closed"}, {LibcameraSource::State::opened, "opened"},
    {LibcameraSource::State::streaming, "streaming"}, {LibcameraSource::State::failed, "failed"},
    {LibcameraSource::State::backoff, "backoff"}};
constexpr base::EnumName<StreamLoss> kStreamLosses[]{
    {StreamLoss::none, "none"}, {StreamLoss::no_first_frame, "no first frame after the start"},
    {StreamLoss::stalled, "no frame any more"}, {StreamLoss::failed_requests, "requests keep completing with errors"}};

}  // namespace

std::string_view to_string(LibcameraSource::State s) { return base::name_of(kStates, s); }
std::string_view to_string(StreamLoss loss) { return base::name_of(kStreamLosses, loss); }

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

    // libcamera's thread: hand the request's index over, wake next(). No
    // locks, no allocation, no logging here.
    void completed(libcamera::Request* request)
    {
        in_camera.fetch_sub(1, std::memory_order_acq_rel);
        if (!ring->try_push(request->cookie()))
            ring_full.fetch_add(1, std::memory_order_relaxed);
        wake();
    }
    // The manager's thread: some camera went away (needs udev hotplug).
    void removed(std::shared_ptr<libcamera::Camera> gone)
    {
        if (gone.get() == watched.load(std::memory_order_acquire))
            unplugged();
    }
    void unplugged()
    {
        disconnected.store(true, std::memory_order_release);
        wake();
    }
    void wake() const
    {
        const std::uint64_t one = 1;
        [[maybe_unused]] const ssize_t n = ::write(event_fd.get(), &one, sizeof one);  // only fails if the counter is saturated
    }

    std::unique_ptr<libcamera::CameraManager, ManagerStopper> manager;
    std::shared_ptr<libcamera::Camera> camera;
    bool acquired = false;
    bool started = false;
    bool connected = false;  // our slots are connected to the camera's and manager's signals
    std::atomic<const libcamera::Camera*> watched{nullptr};  // for cameraRemoved
    std::unique_ptr<libcamera::CameraConfiguration> config;
    libcamera::Stream* stream = nullptr;
    std::size_t stride = 0;
    std::unique_ptr<libcamera::FrameBufferAllocator> allocator;
    std::vector<std::unique_ptr<libcamera::Request>> requests;  // index = cookie
    std::vector<base::MappedMemory> planes;                           // index = cookie
    std::unique_ptr<base::SpscRing<std::uint64_t>> ring;
    base::UniqueFd event_fd;
    std::atomic<bool> disconnected{false};
    std::atomic<std::uint64_t> ring_full{0};
    std::atomic<int> in_camera{0};  // requests queued and not completed yet
};

// --- LibcameraSource -------------------------------------------------------------

LibcameraSource::LibcameraSource(LibcameraOptions options, std::shared_ptr<spdlog::logger> log)
    : options_(std::move(options)),
      log_(std::move(log)),
      name_("libcamera:" + options_.camera),
      backoff_(options_.reopen_min, options_.reopen_max),
      watchdog_(options_.first_frame_timeout.count(), options_.stall_timeout.count(), options_.max_failed_requests)
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
        log_->error("{}: open() in state {}", name_, to_string(state_));
        return false;
    }
    if (!open_camera(options_.camera)) {
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

bool LibcameraSource::error(const std::string& what)
{
    SourceCounterCells::bump(counters_.errors);
    if (reopening_)
        attempt_error_ = what;
    else
        log_->error("{}: {}", name_, what);
    return false;
}

bool LibcameraSource::open_camera(const std::string& selector)
{
    impl_ = std::make_unique<Impl>();
    Impl& m = *impl_;

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
    const auto index = select_camera(ids, selector, why);
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
    m.ring = std::make_unique<base::SpscRing<std::uint64_t>>(m.requests.size());
    m.event_fd.reset(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC));
    if (!m.event_fd.valid())
        return error("eventfd: " + errno_text(errno));
    m.camera->requestCompleted.connect(&m, &Impl::completed);
    m.camera->disconnected.connect(&m, &Impl::unplugged);
    m.manager->cameraRemoved.connect(&m, &Impl::removed);
    m.watched.store(m.camera.get(), std::memory_order_release);
    m.connected = true;
    return true;
}

bool LibcameraSource::start()
{
    if (state_ != State::opened) {
        log_->error("{}: start() in state {} (open() first)", name_, to_string(state_));
        return false;
    }
    if (!start_camera()) {
        close_camera();
        state_ = State::failed;
        return false;
    }
    return true;
}

bool LibcameraSource::start_camera()
{
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
    if (r < 0)
        return error("Camera::start: " + errno_text(r));
    m.started = true;
    if (!set_rate && options_.fps > 0 && !reopening_)
        log_->info("{}: the camera does not set a frame rate (no FrameDurationLimits); using its own", name_);
    for (auto& request : m.requests) {
        m.in_camera.fetch_add(1, std::memory_order_acq_rel);
        if ((r = m.camera->queueRequest(request.get())) < 0) {
            m.in_camera.fetch_sub(1, std::memory_order_acq_rel);
            return error("Camera::queueRequest: " + errno_text(r));
        }
    }
    state_ = State::streaming;
    watchdog_.started(base::monotonic_ns());
    return true;
}

void LibcameraSource::close_camera()
{
    if (!impl_)
        return;
    Impl& m = *impl_;
    // A camera whose device nodes are gone (see media_nodes_unregistered())
    // can be stopped only once every request is back: the kernel's queue
    // release normally returns them all (as errors) soon after the unplug.
    if (m.started && m.in_camera.load(std::memory_order_acquire) > 0 && media_nodes_unregistered()) {
        const std::int64_t give_up = base::monotonic_ns() + kDrainNs;
        while (m.in_camera.load(std::memory_order_acquire) > 0 && base::monotonic_ns() < give_up) {
            pollfd pfd{m.event_fd.get(), POLLIN, 0};
            if (::poll(&pfd, 1, 10) > 0) {
                std::uint64_t count = 0;
                [[maybe_unused]] const ssize_t n = ::read(m.event_fd.get(), &count, sizeof count);
            }
        }
        if (const int stuck = m.in_camera.load(std::memory_order_acquire); stuck > 0) {
            // libcamera 0.0.3 aborts in Camera::stop() (requests still
            // queued) and terminates when a running camera is destroyed:
            // neither is survivable. Leave the camera as it is for good.
            log_->error("{}: the camera's device nodes are gone with {} requests stuck in the driver; libcamera "
                        "0.0.3 cannot release it: the source stops (restart the process to recover)",
                        name_, stuck);
            [[maybe_unused]] Impl* leaked = impl_.release();
            wedged_ = true;
            return;
        }
    }
    if (m.started)
        m.camera->stop();  // completes (cancels) every queued request first
    m.started = false;
    if (m.connected) {
        m.camera->requestCompleted.disconnect(&m, &Impl::completed);
        m.camera->disconnected.disconnect(&m, &Impl::unplugged);
        m.manager->cameraRemoved.disconnect(&m, &Impl::removed);
        m.watched.store(nullptr, std::memory_order_release);
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

NextStatus LibcameraSource::lose(const std::string& why)
{
    SourceCounterCells::bump(counters_.errors);
    lost_.fetch_add(1, std::memory_order_relaxed);
    close_camera();
    if (wedged_) {
        state_ = State::failed;
        return NextStatus::failed;
    }
    const std::int64_t now = base::monotonic_ns();
    backoff_.reset();
    backoff_.on_failure(now);
    log_->warn("{}: camera '{}' lost ({}); released, looking for it again in {} ms (backoff up to {} ms)", name_,
               camera_id_, why, backoff_.wait_ns(now) / 1'000'000, backoff_.max_ns() / 1'000'000);
    logged_attempt_error_.clear();
    state_ = State::backoff;
    return NextStatus::timeout;
}

NextStatus LibcameraSource::try_reopen(std::chrono::nanoseconds timeout)
{
    const std::int64_t now = base::monotonic_ns();
    if (!backoff_.due(now)) {
        base::sleep_for_ns(std::min<std::int64_t>(backoff_.wait_ns(now), timeout.count()));
        if (!backoff_.due(base::monotonic_ns())) {
            SourceCounterCells::bump(counters_.timeouts);
            return NextStatus::timeout;
        }
    }
    reopening_ = true;
    attempt_error_.clear();
    const bool ok = open_camera(camera_id_.empty() ? options_.camera : camera_id_) && start_camera();
    reopening_ = false;
    if (!ok) {
        close_camera();
        backoff_.on_failure(base::monotonic_ns());
        // Attempts fail the same way while the camera is away: log the reason when it changes.
        if (attempt_error_ != logged_attempt_error_) {
            log_->warn("{}: camera '{}' not back: {}; retrying with backoff", name_, camera_id_, attempt_error_);
            logged_attempt_error_ = attempt_error_;
        }
        state_ = State::backoff;
        SourceCounterCells::bump(counters_.timeouts);
        return NextStatus::timeout;
    }
    backoff_.on_success();
    SourceCounterCells::bump(counters_.reopens);
    log_->info("{}: camera '{}' is back; streaming again (reopen {})", name_, camera_id_,
               counters_.reopens.load(std::memory_order_relaxed));
    return NextStatus::timeout;
}

NextStatus LibcameraSource::next(Frame& into, std::chrono::nanoseconds timeout)
{
    if (state_ == State::backoff) {
        const NextStatus reopened = try_reopen(timeout);
        if (state_ != State::streaming)
            return reopened;
    }
    if (state_ != State::streaming)
        return NextStatus::failed;
    Impl& m = *impl_;
    const std::int64_t deadline = base::monotonic_ns() + timeout.count();
    std::uint64_t index = 0;
    while (!m.ring->try_pop(index)) {
        if (m.disconnected.load(std::memory_order_acquire))
            return lose("the camera was disconnected");
        const std::int64_t now = base::monotonic_ns();
        if (const StreamLoss loss = watchdog_.check(now); loss != StreamLoss::none)
            return lose(fmt::format("{} within {} ms", to_string(loss), watchdog_.limit_ns() / 1'000'000));
        const std::int64_t left = deadline - now;
        if (left <= 0) {
            SourceCounterCells::bump(counters_.timeouts);
            return NextStatus::timeout;
        }
        pollfd pfd{m.event_fd.get(), POLLIN, 0};
        const int r = ::poll(&pfd, 1, static_cast<int>((left + 999'999) / 1'000'000));
        if (r < 0 && errno != EINTR)
            return lose("poll on the completion eventfd: " + errno_text(errno));
        if (r > 0) {
            std::uint64_t count = 0;
            [[maybe_unused]] const ssize_t n = ::read(m.event_fd.get(), &count, sizeof count);  // EAGAIN: already drained
        }
    }
    const std::int64_t dequeued_ns = base::monotonic_ns();
    if (index >= m.requests.size())
        return lose(fmt::format("completed request has an unknown index {}", index));
    libcamera::Request* request = m.requests[index].get();
    libcamera::FrameBuffer* buffer = request->findBuffer(m.stream);

    bool deliver = true;
    const libcamera::FrameMetadata* meta = buffer ? &buffer->metadata() : nullptr;
    const std::size_t bytesused =
        meta && !meta->planes().empty() ? meta->planes()[0].bytesused : 0;
    if (request->status() != libcamera::Request::RequestComplete || meta == nullptr ||
        meta->status != libcamera::FrameMetadata::FrameSuccess) {
        SourceCounterCells::bump(counters_.corrupt);
        watchdog_.failed_request();
        skipped_log_.warn(*log_, dequeued_ns, "{}: request {} {} (frame status {})", name_, index,
                          request->status() == libcamera::Request::RequestCancelled ? "cancelled" : "not complete",
                          meta ? static_cast<int>(meta->status) : -1);
        deliver = false;
    } else {
        watchdog_.frame(dequeued_ns);  // the camera delivers, whether or not the slot fits
        const PlaneStatus copied =
            copy_plane_to_bgr(m.planes[index].bytes(), std::min(bytesused, m.planes[index].length()), m.stride,
                              options_.size, order_, into.bgr);
        if (copied == PlaneStatus::bad_size) {
            SourceCounterCells::bump(counters_.bad_size);
            skipped_log_.wrong_size(*log_, dequeued_ns, name_, options_.size, into.bgr);
            deliver = false;
        } else if (copied == PlaneStatus::corrupt) {
            SourceCounterCells::bump(counters_.corrupt);
            skipped_log_.warn(*log_, dequeued_ns, "{}: frame {} has {} bytes, {}x{} at stride {} needs more", name_,
                              meta->sequence, bytesused, options_.size.width, options_.size.height, m.stride);
            deliver = false;
        }
    }
    const std::optional<std::int64_t> sensor_ns = request->metadata().get(libcamera::controls::SensorTimestamp);
    const std::uint64_t sequence = meta ? meta->sequence : 0;

    request->reuse(libcamera::Request::ReuseBuffers);
    m.in_camera.fetch_add(1, std::memory_order_acq_rel);
    if (const int r = m.camera->queueRequest(request); r < 0) {
        m.in_camera.fetch_sub(1, std::memory_order_acq_rel);
        return lose("Camera::queueRequest: " + errno_text(r));
    }
    if (watchdog_.failed_in_row() > 0 && watchdog_.check(dequeued_ns) == StreamLoss::failed_requests)
        return lose(fmt::format("{} requests in a row completed with an error", watchdog_.failed_in_row()));
    if (!deliver)
        return NextStatus::skipped;

    if (!sensor_ns)
        unstamped_.fetch_add(1, std::memory_order_relaxed);
    into.t_sample_ns = libcamera_capture_time_ns(sensor_ns, dequeued_ns);
    into.t_delivered_ns = dequeued_ns;
    into.t_recorded_ns = into.t_sample_ns;
    into.source_seq = sequence;
    into.name.assign(name_);
    SourceCounterCells::bump(counters_.delivered);
    return NextStatus::frame;
}

SourceCounters LibcameraSource::counters() const
{
    return counters_.load();
}

LibcameraCounters LibcameraSource::libcamera_counters() const
{
    return {counters_.load(), unstamped_.load(std::memory_order_relaxed), lost_.load(std::memory_order_relaxed)};
}

}  // namespace stemd::drivers
