#include "gpiod/gpiod_lines.hpp"

#include <gpiod.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include <spdlog/fmt/fmt.h>
#include "stemd/base/clock.hpp"
#include "stemd/base/enum_names.hpp"

namespace stemd::drivers {

namespace {

constexpr const char* kConsumer = "stemd";
constexpr std::size_t kMaxEvents = 16;

timespec to_timespec(std::int64_t ns)
{
    if (ns < 0)
        ns = 0;
    return {static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
}

constexpr base::EnumName<EncoderMode> kEncoderModes[]{
    {EncoderMode::none, "none"}, {EncoderMode::quadrature, "quadrature"}, {EncoderMode::single, "single"}};
constexpr base::EnumName<GpiodState> kGpiodStates[]{
    {GpiodState::closed, "closed"}, {GpiodState::up, "up"}, {GpiodState::down, "down"}};

}  // namespace

std::string_view to_string(GpiodState s) { return base::name_of(kGpiodStates, s); }

// The open chip and its requested lines: released, then closed, exactly once.
struct GpiodLines::Chip {
    gpiod_chip* chip = nullptr;
    gpiod_line* enable = nullptr;
    gpiod_line* trigger = nullptr;
    gpiod_line* enc_a = nullptr;
    gpiod_line* enc_b = nullptr;

    Chip() = default;
    Chip(const Chip&) = delete;
    Chip& operator=(const Chip&) = delete;
    ~Chip()
    {
        for (gpiod_line* l : {enable, trigger, enc_a, enc_b}) {
            if (l != nullptr)
                gpiod_line_release(l);
        }
        if (chip != nullptr)
            gpiod_chip_close(chip);
    }
};

GpiodLines::GpiodLines(GpiodOptions options, std::shared_ptr<spdlog::logger> log)
    : options_(std::move(options)),
      log_(std::move(log)),
      name_("gpiod:" + options_.chip),
      backoff_(options_.reopen_min_ns, options_.reopen_max_ns),
      debouncer_(options_.enable_debounce_ns)
{
}

GpiodLines::~GpiodLines()
{
    stop();
    const std::lock_guard lock(io_mutex_);
    chip_.reset();
}

std::string GpiodLines::last_error() const
{
    const std::lock_guard lock(error_mutex_);
    return last_error_;
}

void GpiodLines::fail(const char* what, int line, int err)
{
    errors_.fetch_add(1, std::memory_order_relaxed);
    std::string where = line >= 0 ? fmt::format("{} line {}", options_.chip, line) : options_.chip;
    std::string message = fmt::format("{} on {}: {} (errno {})", what, where, std::strerror(err), err);
    const std::lock_guard lock(error_mutex_);
    // Repeated reopen attempts fail the same way: log a failure once, until it changes.
    if (message != last_error_)
        log_->error("{}: {}", name_, message);
    last_error_ = std::move(message);
}

bool GpiodLines::try_open()
{
    const GpiodOptions& o = options_;
    const bool quad = o.encoder == EncoderMode::quadrature;
    if ((o.encoder != EncoderMode::none && o.encoder_a_line < 0) || (quad && o.encoder_b_line < 0)) {
        fail(quad ? "quadrature encoder needs encoder_a_line and encoder_b_line" : "encoder needs encoder_a_line", -1,
             EINVAL);
        return false;
    }
    auto c = std::make_unique<Chip>();
    errno = 0;
    c->chip = gpiod_chip_open_lookup(o.chip.c_str());
    if (c->chip == nullptr) {
        fail("gpiod_chip_open_lookup (no such GPIO chip?)", -1, errno != 0 ? errno : ENOENT);
        return false;
    }
    auto get = [&](int offset) -> gpiod_line* {
        gpiod_line* l = gpiod_chip_get_line(c->chip, static_cast<unsigned>(offset));
        if (l == nullptr)
            fail("gpiod_chip_get_line", offset, errno != 0 ? errno : EINVAL);
        return l;
    };
    auto request_edges = [&](gpiod_line*& slot, int offset, bool active_low) {
        gpiod_line* l = get(offset);
        if (l == nullptr)
            return false;
        const int flags = active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
        if (gpiod_line_request_both_edges_events_flags(l, kConsumer, flags) < 0) {
            fail("gpiod_line_request_both_edges_events_flags", offset, errno);
            return false;
        }
        slot = l;
        return true;
    };

    const int enable = static_cast<int>(o.enable_line);
    if (!request_edges(c->enable, enable, o.enable_active_low))
        return false;
    if (o.trigger_line >= 0) {
        gpiod_line* l = get(o.trigger_line);
        if (l == nullptr)
            return false;
        const int flags = o.trigger_active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
        if (gpiod_line_request_output_flags(l, kConsumer, flags, 0) < 0) {
            fail("gpiod_line_request_output_flags", o.trigger_line, errno);
            return false;
        }
        c->trigger = l;
    }
    if (o.encoder != EncoderMode::none) {
        if (!request_edges(c->enc_a, o.encoder_a_line, false))
            return false;
        if (quad && !request_edges(c->enc_b, o.encoder_b_line, false))
            return false;
    }

    const int level = gpiod_line_get_value(c->enable);
    if (level < 0) {
        fail("gpiod_line_get_value (enable)", enable, errno);
        return false;
    }
    chip_ = std::move(c);
    debouncer_.reset(level != 0, base::monotonic_ns());
    if (quad) {
        const int a = gpiod_line_get_value(chip_->enc_a);
        const int b = gpiod_line_get_value(chip_->enc_b);
        if (a < 0 || b < 0) {
            fail("gpiod_line_get_value (encoder)", a < 0 ? o.encoder_a_line : o.encoder_b_line, errno);
            chip_.reset();
            debouncer_.force_disabled();
            return false;
        }
        decoder_.reset(static_cast<std::uint8_t>((a << 1) | b));  // ticks carry over a reopen
    }
    publish_enable();
    return true;
}

bool GpiodLines::open()
{
    bool ok = false;
    {
        const std::lock_guard lock(io_mutex_);
        if (chip_)
            return true;
        ok = try_open();
        if (ok) {
            set_state(GpiodState::up);
            was_up_ = true;
            backoff_.on_success();
        } else {
            backoff_.reset();  // an explicit open(): the schedule starts at reopen_min
            backoff_.on_failure(base::monotonic_ns());
            set_state(GpiodState::down);
        }
    }
    if (ok) {
        log_->info("{}: open, enable line {}{}, trigger {}, encoder {}", name_, options_.enable_line,
                   options_.enable_active_low ? " (active-low)" : "",
                   options_.trigger_line >= 0 ? fmt::format("line {}", options_.trigger_line) : std::string("none"),
                   base::name_of(kEncoderModes, options_.encoder));
        const std::lock_guard lock(error_mutex_);
        last_error_.clear();
    }
    return ok;
}

void GpiodLines::go_down(const char* what, int line, int err)
{
    chip_.reset();
    debouncer_.force_disabled();
    publish_enable();
    fail(what, line, err);
    log_->warn("{}: lines lost, enable forced off; reopening with backoff ({} ms .. {} ms)", name_,
               options_.reopen_min_ns / 1'000'000, options_.reopen_max_ns / 1'000'000);
    backoff_.on_failure(base::monotonic_ns());  // it was up: the delay is back at reopen_min
    set_state(GpiodState::down);
}

void GpiodLines::publish_enable()
{
    const bool now = debouncer_.enabled();
    bounces_.store(debouncer_.bounces(), std::memory_order_relaxed);
    if (enabled_.load(std::memory_order_relaxed) == now)
        return;
    {
        const std::lock_guard lock(change_mutex_);
        enabled_.store(now, std::memory_order_release);
    }
    change_cv_.notify_all();
}

bool GpiodLines::wait_change(bool seen, std::int64_t timeout_ns)
{
    std::unique_lock lock(change_mutex_);
    return change_cv_.wait_for(lock, std::chrono::nanoseconds(std::max<std::int64_t>(timeout_ns, 0)),
                               [&] { return enabled() != seen; });
}

bool GpiodLines::set_trigger(bool active)
{
    const std::lock_guard lock(io_mutex_);
    if (!chip_ || chip_->trigger == nullptr) {
        errors_.fetch_add(1, std::memory_order_relaxed);
        if (options_.trigger_line < 0)
            log_->error("{}: set_trigger: no trigger line configured", name_);
        return false;
    }
    if (gpiod_line_set_value(chip_->trigger, active ? 1 : 0) < 0) {
        // The GPIO thread notices a lost chip on its fds and reopens.
        fail("gpiod_line_set_value (trigger)", options_.trigger_line, errno);
        return false;
    }
    return true;
}

bool GpiodLines::pulse(std::uint32_t width_us)
{
    // Held for the whole pulse (its width, ~100 us), so that the line cannot
    // be dropped between its two edges.
    std::unique_lock lock(io_mutex_, std::try_to_lock);
    if (!lock.owns_lock()) {
        trigger_busy_.fetch_add(1, std::memory_order_relaxed);
        return false;
    }
    if (!chip_ || chip_->trigger == nullptr) {
        errors_.fetch_add(1, std::memory_order_relaxed);   // down: the GPIO thread reopens and logs
        return false;
    }
    for (const int level : {1, 0}) {
        if (gpiod_line_set_value(chip_->trigger, level) < 0) {
            const int err = errno;
            errors_.fetch_add(1, std::memory_order_relaxed);
            // The GPIO thread notices a lost chip on its fds and reopens.
            std::uint64_t left_out = 0;
            if (trigger_log_.allow(base::monotonic_ns(), left_out))
                log_->error("{}: gpiod_line_set_value (trigger) on {} line {}: {} (errno {}; {} more failures "
                            "since the last line)",
                            name_, options_.chip, options_.trigger_line, std::strerror(err), err, left_out);
            return false;
        }
        if (level == 1)
            base::sleep_for_ns(static_cast<std::int64_t>(width_us) * 1000);
    }
    pulses_.fetch_add(1, std::memory_order_relaxed);
    return true;
}

EncoderReading GpiodLines::encoder() const
{
    EncoderReading r;
    r.ticks = ticks_.load(std::memory_order_relaxed);
    r.direction = direction_.load(std::memory_order_relaxed);
    r.invalid = invalid_.load(std::memory_order_relaxed);
    return r;
}

GpioCounters GpiodLines::counters() const
{
    GpioCounters c;
    c.edges = edges_.load(std::memory_order_relaxed);
    c.enable_bounces = bounces_.load(std::memory_order_relaxed);
    c.errors = errors_.load(std::memory_order_relaxed);
    c.reopens = reopens_.load(std::memory_order_relaxed);
    c.trigger_pulses = pulses_.load(std::memory_order_relaxed);
    c.trigger_busy = trigger_busy_.load(std::memory_order_relaxed);
    return c;
}

void GpiodLines::start()
{
    if (thread_.joinable())
        return;
    stop_fd_.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
    if (!stop_fd_.valid()) {
        fail("eventfd", -1, errno);
        return;
    }
    thread_ = std::thread([this] { run(); });
}

void GpiodLines::stop()
{
    if (thread_.joinable()) {
        const std::uint64_t one = 1;
        if (::write(stop_fd_.get(), &one, sizeof one) < 0)
            fail("eventfd write", -1, errno);
        thread_.join();
    }
    stop_fd_.reset();
}

void GpiodLines::sample_encoder()
{
    const int a = gpiod_line_get_value(chip_->enc_a);
    const int b = gpiod_line_get_value(chip_->enc_b);
    if (a < 0 || b < 0) {
        fail("gpiod_line_get_value (encoder)", a < 0 ? options_.encoder_a_line : options_.encoder_b_line, errno);
        return;
    }
    const QuadStep s = decoder_.sample(static_cast<std::uint8_t>((a << 1) | b));
    ticks_.store(decoder_.ticks(), std::memory_order_relaxed);
    invalid_.store(decoder_.invalid(), std::memory_order_relaxed);
    if (s == QuadStep::forward)
        direction_.store(1, std::memory_order_relaxed);
    else if (s == QuadStep::backward)
        direction_.store(-1, std::memory_order_relaxed);
}

// which: 0 enable, 1 encoder A, 2 encoder B.
bool GpiodLines::handle_events(int which, std::int64_t now_ns)
{
    gpiod_line* line = which == 0 ? chip_->enable : which == 1 ? chip_->enc_a : chip_->enc_b;
    const int offset = which == 0 ? static_cast<int>(options_.enable_line)
                                  : which == 1 ? options_.encoder_a_line : options_.encoder_b_line;
    gpiod_line_event events[kMaxEvents];
    const int n = gpiod_line_event_read_multiple(line, events, kMaxEvents);
    if (n < 0) {
        const std::lock_guard lock(io_mutex_);
        go_down("gpiod_line_event_read_multiple", offset, errno);
        return false;
    }
    edges_.fetch_add(static_cast<std::uint64_t>(n), std::memory_order_relaxed);
    if (which == 0) {
        // The event's type is the logical level when the kernel looked (active-low applied).
        for (int i = 0; i < n; ++i)
            debouncer_.sample(events[i].event_type == GPIOD_LINE_EVENT_RISING_EDGE, now_ns);
        publish_enable();
    } else if (options_.encoder == EncoderMode::single) {
        std::int64_t rising = 0;
        for (int i = 0; i < n; ++i)
            rising += events[i].event_type == GPIOD_LINE_EVENT_RISING_EDGE ? 1 : 0;
        if (rising > 0) {
            ticks_.fetch_add(rising, std::memory_order_relaxed);
            direction_.store(1, std::memory_order_relaxed);
        }
    } else {
        sample_encoder();
    }
    return true;
}

void GpiodLines::run()
{
    for (;;) {
        std::int64_t now = base::monotonic_ns();
        if (state() != GpiodState::up && backoff_.due(now)) {
            bool ok = false;
            {
                const std::lock_guard lock(io_mutex_);
                ok = try_open();
                if (ok) {
                    set_state(GpiodState::up);
                    backoff_.on_success();
                    next_health_ns_ = 0;
                } else {
                    backoff_.on_failure(now);
                    set_state(GpiodState::down);
                }
            }
            if (ok) {
                if (was_up_) {
                    reopens_.fetch_add(1, std::memory_order_relaxed);
                    log_->info("{}: lines reopened", name_);
                } else {
                    log_->info("{}: open", name_);
                }
                was_up_ = true;
                const std::lock_guard lock(error_mutex_);
                last_error_.clear();
            }
        }

        // stop fd, then the requested input lines' event fds.
        pollfd fds[4];
        int which[4] = {-1, -1, -1, -1};
        nfds_t nfds = 0;
        fds[nfds++] = {stop_fd_.get(), POLLIN, 0};
        if (chip_) {
            gpiod_line* lines[3] = {chip_->enable, chip_->enc_a, chip_->enc_b};
            for (int i = 0; i < 3; ++i) {
                if (lines[i] == nullptr)
                    continue;
                which[nfds] = i;
                fds[nfds++] = {gpiod_line_event_get_fd(lines[i]), POLLIN, 0};
            }
        }
        std::int64_t deadline = -1;
        if (chip_) {
            if (next_health_ns_ == 0)
                next_health_ns_ = now + options_.health_check_ns;
            deadline = next_health_ns_;
            const std::int64_t debounce = debouncer_.next_deadline_ns();
            if (debounce >= 0)
                deadline = std::min(deadline, debounce);
        } else {
            deadline = std::max<std::int64_t>(backoff_.next_attempt_ns(), 0);
        }
        timespec ts{};
        const timespec* timeout = nullptr;
        if (deadline >= 0) {
            ts = to_timespec(deadline - now);
            timeout = &ts;
        }
        const int r = ::ppoll(fds, nfds, timeout, nullptr);
        if (r < 0) {
            if (errno == EINTR)
                continue;
            fail("ppoll", -1, errno);
            continue;
        }
        if ((fds[0].revents & POLLIN) != 0)
            return;
        now = base::monotonic_ns();
        for (nfds_t i = 1; i < nfds && chip_; ++i) {
            const short re = fds[i].revents;
            if (re == 0)
                continue;
            if ((re & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
                const int offset = which[i] == 0 ? static_cast<int>(options_.enable_line)
                                                 : which[i] == 1 ? options_.encoder_a_line : options_.encoder_b_line;
                const std::lock_guard lock(io_mutex_);
                go_down("poll on the line's event fd reported an error (chip removed?)", offset, ENODEV);
                break;
            }
            if (!handle_events(which[i], now))
                break;
        }
        now = base::monotonic_ns();
        if (chip_ && now >= next_health_ns_) {
            next_health_ns_ = now + options_.health_check_ns;
            const int level = gpiod_line_get_value(chip_->enable);
            if (level < 0) {
                const int err = errno;
                const std::lock_guard lock(io_mutex_);
                go_down("gpiod_line_get_value (enable health check; chip removed?)",
                        static_cast<int>(options_.enable_line), err);
            } else {
                debouncer_.sample(level != 0, now);
            }
        }
        if (chip_) {
            debouncer_.on_time(now);
            publish_enable();
        }
    }
}

}  // namespace stemd::drivers
