#include "v4l2/paired_nir_source.hpp"

#include <time.h>

#include <algorithm>
#include <limits>
#include <utility>

#include <opencv2/core.hpp>
#include "stemd/base/clock.hpp"

namespace stemd::drivers {

namespace {

}  // namespace

void PairedNirSource::Side::reset()
{
    free_count = 0;
    for (std::uint32_t i = 0; i < kSlots; ++i)
        give(i);
}

PairedNirOptions PairedNirSource::normalised(PairedNirOptions options)
{
    options.nir.pixel_format = V4l2PixelFormat::grey;
    options.nir.size = options.rgb.size;
    if (!options.nir.clock)
        options.nir.clock = options.rgb.clock;
    if (options.poll_slice <= std::chrono::nanoseconds::zero())
        options.poll_slice = std::chrono::milliseconds(1);
    return options;
}

PairedNirSource::PairedNirSource(PairedNirOptions options, std::shared_ptr<spdlog::logger> log)
    : options_(normalised(std::move(options))),
      log_(std::move(log)),
      name_("paired:" + options_.rgb.device + "+" + options_.nir.device),
      rgb_(options_.rgb, log_),
      nir_(options_.nir, log_),
      pairer_(options_.tolerance.count())
{
    rgb_side_.reset();
    nir_side_.reset();
}

PairedNirSource::~PairedNirSource()
{
    stop();
}

std::int64_t PairedNirSource::now_ns() const
{
    return options_.rgb.clock ? options_.rgb.clock() : base::monotonic_ns();
}

bool PairedNirSource::open()
{
    if (options_.rgb.device == options_.nir.device) {
        log_->error("{}: the RGB and the NIR camera are the same device {}", name_, options_.rgb.device);
        return false;
    }
    // Every slot once, here: next() only writes into them.
    for (Side* side : {&rgb_side_, &nir_side_}) {
        for (Frame& f : side->slots)
            f.bgr = cv::Mat(options_.rgb.size, CV_8UC3, cv::Scalar::all(0));
        side->reset();
    }
    pairer_.clear();
    if (!rgb_.open())
        return false;
    if (!nir_.open()) {
        rgb_.stop();
        return false;
    }
    opened_ = true;
    log_->info("{}: pairing by capture time within {:.1f} ms", name_,
               static_cast<double>(options_.tolerance.count()) / 1e6);
    return true;
}

bool PairedNirSource::start()
{
    if (!opened_) {
        log_->error("{}: start() before open()", name_);
        return false;
    }
    // Back to back, so that both streams start at about the same time.
    if (!rgb_.start() || !nir_.start()) {
        rgb_.stop();
        nir_.stop();
        opened_ = false;
        return false;
    }
    return true;
}

void PairedNirSource::stop()
{
    rgb_.stop();
    nir_.stop();
    release_pending();
    opened_ = false;
}

void PairedNirSource::release_pending()
{
    pairer_.clear();
    rgb_side_.reset();
    nir_side_.reset();
}

bool PairedNirSource::handle(const PairDecision& d, Frame& into, NextStatus& status)
{
    const auto sync = [this] {
        const PairingCounters& c = pairer_.counters();
        unpaired_rgb_.store(c.unpaired_rgb, std::memory_order_relaxed);
        unpaired_nir_.store(c.unpaired_nir, std::memory_order_relaxed);
        forced_.store(c.forced, std::memory_order_relaxed);
        out_of_order_.store(c.out_of_order, std::memory_order_relaxed);
    };
    sync();
    switch (d.kind) {
    case PairDecision::Kind::unpaired_rgb:
        rgb_side_.give(d.rgb_id);
        return false;
    case PairDecision::Kind::unpaired_nir:
        nir_side_.give(d.nir_id);
        return false;
    case PairDecision::Kind::paired: break;
    }
    const Frame& rgb = rgb_side_.slots[d.rgb_id];
    const Frame& nir = nir_side_.slots[d.nir_id];
    const cv::Size size = options_.rgb.size;
    if (into.bgr.size() != size || into.bgr.type() != CV_8UC3 || into.nir.size() != size ||
        into.nir.type() != CV_8UC1) {
        SourceCounterCells::bump(counters_.bad_size);
        log_->warn("{}: the slot (bgr {}x{} type {}, nir {}x{} type {}) does not fit {}x{} BGR + NIR; pair skipped",
                   name_, into.bgr.cols, into.bgr.rows, into.bgr.type(), into.nir.cols, into.nir.rows,
                   into.nir.type(), size.width, size.height);
        status = NextStatus::skipped;
    } else {
        // Same size and type: both write into the slot's own buffers.
        rgb.bgr.copyTo(into.bgr);
        cv::extractChannel(nir.bgr, into.nir, 0);  // the GREY plane (V4l2Source expanded it to B = G = R)
        into.t_sample_ns = rgb.t_sample_ns;
        into.t_delivered_ns = now_ns();
        into.t_recorded_ns = rgb.t_recorded_ns;
        into.source_seq = rgb.source_seq;
        into.name.assign(name_);
        last_offset_ns_.store(d.nir_t_ns - d.rgb_t_ns, std::memory_order_relaxed);
        SourceCounterCells::bump(counters_.delivered);
        status = NextStatus::frame;
    }
    rgb_side_.give(d.rgb_id);
    nir_side_.give(d.nir_id);
    return true;
}

NextStatus PairedNirSource::next(Frame& into, std::chrono::nanoseconds timeout)
{
    if (!opened_)
        return NextStatus::failed;
    const std::int64_t start = now_ns();
    const std::int64_t wait = std::clamp<std::int64_t>(timeout.count(), 0, std::numeric_limits<std::int64_t>::max() - std::max<std::int64_t>(start, 0));
    const std::int64_t deadline = start + wait;
    NextStatus status = NextStatus::timeout;
    for (;;) {
        while (const auto d = pairer_.decide()) {
            if (handle(*d, into, status))
                return status;
        }
        const PairSide side = turn_;
        turn_ = side == PairSide::rgb ? PairSide::nir : PairSide::rgb;
        while (pairer_.full(side)) {
            const auto d = pairer_.force(side);
            if (!d)
                break;
            if (handle(*d, into, status))
                return status;
        }

        const std::int64_t remaining = deadline - now_ns();
        // A zero timeout still looks at one device once.
        const std::int64_t slice = std::clamp<std::int64_t>(remaining, 0, options_.poll_slice.count());
        V4l2Source& source = side == PairSide::rgb ? rgb_ : nir_;
        Side& slots = side == PairSide::rgb ? rgb_side_ : nir_side_;
        const std::uint32_t id = slots.take();  // pending <= kPending < kSlots
        Frame& slot = slots.slots[id];
        const NextStatus got = source.next(slot, std::chrono::nanoseconds(slice));
        if (got == NextStatus::frame) {
            if (pairer_.push(side, slot.t_sample_ns, id) != PushResult::accepted) {
                slots.give(id);
                if (std::uint64_t left_out = 0; out_of_order_log_.allow(slot.t_sample_ns, left_out))
                    log_->warn("{}: {} frame {} at {} ns is older than its previous one; dropped ({} more not "
                               "logged since the last warning)",
                               name_, side == PairSide::rgb ? "RGB" : "NIR", slot.source_seq, slot.t_sample_ns,
                               left_out);
                out_of_order_.store(pairer_.counters().out_of_order, std::memory_order_relaxed);
                unpaired_rgb_.store(pairer_.counters().unpaired_rgb, std::memory_order_relaxed);
                unpaired_nir_.store(pairer_.counters().unpaired_nir, std::memory_order_relaxed);
            }
            continue;  // decide at once
        }
        slots.give(id);
        if (got == NextStatus::failed || got == NextStatus::end_of_stream) {
            log_->error("{}: the {} device failed", name_, side == PairSide::rgb ? "RGB" : "NIR");
            return NextStatus::failed;
        }
        // A device reopening delivers nothing captured before now.
        if (source.state() == V4l2Source::State::backoff)
            pairer_.advance(side, now_ns());
        if (remaining <= 0) {
            SourceCounterCells::bump(counters_.timeouts);
            return NextStatus::timeout;
        }
    }
}

SourceCounters PairedNirSource::counters() const
{
    const SourceCounters r = rgb_.counters();
    const SourceCounters n = nir_.counters();
    SourceCounters c = counters_.load();
    c.errors = r.errors + n.errors;
    c.reopens = r.reopens + n.reopens;
    c.corrupt = r.corrupt + n.corrupt;
    c.bad_size += r.bad_size + n.bad_size;
    return c;
}

PairedNirCounters PairedNirSource::paired_counters() const
{
    return {.delivered = counters_.delivered.load(std::memory_order_relaxed),
            .unpaired_rgb = unpaired_rgb_.load(std::memory_order_relaxed),
            .unpaired_nir = unpaired_nir_.load(std::memory_order_relaxed),
            .forced = forced_.load(std::memory_order_relaxed),
            .out_of_order = out_of_order_.load(std::memory_order_relaxed),
            .bad_size = counters_.bad_size.load(std::memory_order_relaxed),
            .last_offset_ns = last_offset_ns_.load(std::memory_order_relaxed),
            .rgb = rgb_.counters(),
            .nir = nir_.counters()};
}

}  // namespace stemd::drivers
