// Pairs frames of two cameras triggered together (an RGB camera and a mono
// NIR camera) by capture timestamp: pure logic on CLOCK_MONOTONIC ns that the
// caller passes in, header-only, no allocation (fixed arrays), so tests drive
// it with fake timestamps. It holds only timestamps and the caller's ids (slot
// indices): the caller keeps the pixels.
//
// Rule (time-ordered greedy, nearest within tolerance): RGB frames are
// decided in capture-time order. The oldest undecided RGB frame takes the
// unused NIR frame nearest to it in time (pending or still to come; on a tie
// the earlier NIR frame) if that one is within tolerance_ns (|rgb_t - nir_t|
// <= tolerance_ns); else it is unpaired. A NIR frame no RGB frame takes is
// unpaired. NIR frames older than one just paired are unpaired at once (no
// later RGB frame can prefer them). With a constant clock offset below the
// tolerance, every frame pairs with its partner. Keep the tolerance below half
// the frame period: above it a frame can have two candidates, and the rule
// still pairs consistently but which one is ambiguous.
//
// Decisions are made as soon as they are final. Each side's timestamps must
// not decrease (V4L2 buffer timestamps on CLOCK_MONOTONIC do not), so the
// newest timestamp seen per side (its watermark) bounds every frame still to
// come on that side:
//   - an RGB frame r whose nearest pending NIR lies d away is paired once the
//     NIR watermark is >= r + d (no later NIR can be nearer), d <= tolerance;
//   - r is unpaired once no pending NIR is within tolerance and the NIR
//     watermark is > r + tolerance (e.g. a NIR newer than r + tolerance came);
//   - a NIR frame n is unpaired once no pending RGB is within tolerance and
//     the RGB watermark is > n + tolerance.
// advance(side, t) raises a watermark without a frame: the caller promises no
// frame of that side older than t will come (a device in reopen backoff:
// whatever it delivers after the reopen is newer than now).
//
// The caller holds at most Capacity pending frames per side:
//   while (p.full(side)) handle(p.force(side));  // before capturing on `side`
//   p.push(side, t, id);
//   while (auto d = p.decide()) handle(*d);
// force(side) returns a decision now, as if no more frames of the other side
// were coming: the oldest RGB frame pairs with its nearest pending NIR within
// tolerance or is unpaired; with no RGB pending, the oldest NIR is unpaired.
// Calling it while full(side) always ends (each call removes a frame).
//
// Not thread-safe: one thread (the capture thread) owns it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>

namespace stemd::drivers {

enum class PairSide : std::uint8_t { rgb, nir };

struct PairDecision {
    enum class Kind : std::uint8_t { paired, unpaired_rgb, unpaired_nir };
    Kind kind = Kind::paired;
    // The caller's ids and the frames' timestamps; only the side(s) the
    // decision names are meaningful.
    std::uint32_t rgb_id = 0;
    std::uint32_t nir_id = 0;
    std::int64_t rgb_t_ns = 0;
    std::int64_t nir_t_ns = 0;
    bool forced = false;  // from force(): made before it was final
};

enum class PushResult : std::uint8_t {
    accepted,
    full,          // the side already holds Capacity frames: force() first; nothing stored
    out_of_order,  // older than the side's watermark: rejected, counted as unpaired
};

struct PairingCounters {
    std::uint64_t paired = 0;
    std::uint64_t unpaired_rgb = 0;  // includes out-of-order RGB frames
    std::uint64_t unpaired_nir = 0;  // includes out-of-order NIR frames
    std::uint64_t forced = 0;        // decisions made by force()
    std::uint64_t out_of_order = 0;  // frames older than their side's watermark
};

template <std::size_t Capacity = 4>
class TimestampPairer {
    static_assert(Capacity >= 1, "at least one pending frame per side");

public:
    static constexpr std::size_t kCapacity = Capacity;

    // A negative tolerance is taken as 0 (exact timestamps only).
    explicit constexpr TimestampPairer(std::int64_t tolerance_ns) : tolerance_ns_(tolerance_ns > 0 ? tolerance_ns : 0)
    {
    }

    constexpr std::int64_t tolerance_ns() const { return tolerance_ns_; }
    constexpr std::size_t pending(PairSide side) const { return q(side).size; }
    constexpr bool full(PairSide side) const { return q(side).size >= Capacity; }
    // The newest timestamp seen (or promised by advance()) on `side`; INT64_MIN before any.
    constexpr std::int64_t watermark(PairSide side) const { return q(side).watermark; }
    constexpr const PairingCounters& counters() const { return counters_; }

    // Adds a frame of `side` taken at t_ns, known to the caller as `id`.
    constexpr PushResult push(PairSide side, std::int64_t t_ns, std::uint32_t id)
    {
        Queue& s = q(side);
        if (t_ns < s.watermark) {
            ++counters_.out_of_order;
            ++(side == PairSide::rgb ? counters_.unpaired_rgb : counters_.unpaired_nir);
            return PushResult::out_of_order;
        }
        if (s.size >= Capacity)
            return PushResult::full;
        s.items[s.size++] = Item{t_ns, id};
        s.watermark = t_ns;
        return PushResult::accepted;
    }

    // No frame of `side` older than t_ns will come. Never lowers the watermark.
    constexpr void advance(PairSide side, std::int64_t t_ns)
    {
        Queue& s = q(side);
        if (t_ns > s.watermark)
            s.watermark = t_ns;
    }

    // The next decision that is final given what has been pushed; nullopt:
    // wait for more frames (or advance()).
    constexpr std::optional<PairDecision> decide()
    {
        // NIR frames older than the last paired one: no later RGB takes them.
        if (nir_.size > 0 && have_paired_nir_ && nir_.items[0].t <= last_paired_nir_t_)
            return drop_nir(false);
        if (rgb_.size > 0) {
            const Item r = rgb_.items[0];
            const std::size_t n = nearest_nir(r.t);
            if (n < nir_.size) {
                const std::int64_t d = distance(r.t, nir_.items[n].t);
                if (d <= tolerance_ns_ && nir_.watermark >= sat_add(r.t, d))
                    return pair(n, false);
            }
            const bool none_within = n >= nir_.size || distance(r.t, nir_.items[n].t) > tolerance_ns_;
            if (none_within && nir_.watermark > sat_add(r.t, tolerance_ns_))
                return drop_rgb(false);
        }
        if (nir_.size > 0) {
            const std::int64_t t = nir_.items[0].t;
            bool rgb_within = false;
            for (std::size_t i = 0; i < rgb_.size; ++i)
                rgb_within = rgb_within || distance(rgb_.items[i].t, t) <= tolerance_ns_;
            if (!rgb_within && rgb_.watermark > sat_add(t, tolerance_ns_))
                return drop_nir(false);
        }
        return std::nullopt;
    }

    // A decision now that frees room (see the header comment); nullopt only
    // when nothing is pending at all.
    constexpr std::optional<PairDecision> force(PairSide side)
    {
        if (auto d = decide())
            return d;
        if (side == PairSide::nir && rgb_.size == 0) {
            if (nir_.size == 0)
                return std::nullopt;
            return drop_nir(true);
        }
        if (rgb_.size == 0)
            return nir_.size > 0 ? std::optional<PairDecision>(drop_nir(true)) : std::nullopt;
        const std::size_t n = nearest_nir(rgb_.items[0].t);
        if (n < nir_.size && distance(rgb_.items[0].t, nir_.items[n].t) <= tolerance_ns_)
            return pair(n, true);
        return drop_rgb(true);
    }

    // Forgets every pending frame and watermark (counters kept): after the
    // caller dropped its frames, e.g. at stop().
    constexpr void clear()
    {
        rgb_ = Queue{};
        nir_ = Queue{};
        have_paired_nir_ = false;
        last_paired_nir_t_ = std::numeric_limits<std::int64_t>::min();
    }

    // Pending ids, oldest first (for a caller that releases its slots on clear()).
    constexpr std::uint32_t pending_id(PairSide side, std::size_t i) const { return q(side).items[i].id; }

private:
    struct Item {
        std::int64_t t = 0;
        std::uint32_t id = 0;
    };
    struct Queue {
        std::array<Item, Capacity> items{};
        std::size_t size = 0;
        std::int64_t watermark = std::numeric_limits<std::int64_t>::min();
        constexpr void erase(std::size_t i)
        {
            for (std::size_t k = i + 1; k < size; ++k)
                items[k - 1] = items[k];
            --size;
        }
    };

    constexpr Queue& q(PairSide side) { return side == PairSide::rgb ? rgb_ : nir_; }
    constexpr const Queue& q(PairSide side) const { return side == PairSide::rgb ? rgb_ : nir_; }

    static constexpr std::int64_t distance(std::int64_t a, std::int64_t b)
    {
        // Saturating |a - b| (timestamps near the int64 limits do not overflow).
        const std::int64_t hi = a > b ? a : b;
        const std::int64_t lo = a > b ? b : a;
        if (lo < 0 && hi > std::numeric_limits<std::int64_t>::max() + lo)
            return std::numeric_limits<std::int64_t>::max();
        return hi - lo;
    }
    static constexpr std::int64_t sat_add(std::int64_t a, std::int64_t b)  // b >= 0
    {
        return a > std::numeric_limits<std::int64_t>::max() - b ? std::numeric_limits<std::int64_t>::max() : a + b;
    }

    // Index of the pending NIR nearest to t (the earlier on a tie); nir_.size if none.
    constexpr std::size_t nearest_nir(std::int64_t t) const
    {
        std::size_t best = nir_.size;
        for (std::size_t i = 0; i < nir_.size; ++i) {
            if (best == nir_.size || distance(t, nir_.items[i].t) < distance(t, nir_.items[best].t))
                best = i;
        }
        return best;
    }

    constexpr PairDecision pair(std::size_t n, bool forced)
    {
        PairDecision d{PairDecision::Kind::paired, rgb_.items[0].id, nir_.items[n].id, rgb_.items[0].t,
                       nir_.items[n].t, forced};
        have_paired_nir_ = true;
        last_paired_nir_t_ = nir_.items[n].t;
        rgb_.erase(0);
        nir_.erase(n);
        ++counters_.paired;
        counters_.forced += forced ? 1 : 0;
        return d;
    }
    constexpr PairDecision drop_rgb(bool forced)
    {
        PairDecision d{PairDecision::Kind::unpaired_rgb, rgb_.items[0].id, 0, rgb_.items[0].t, 0, forced};
        rgb_.erase(0);
        ++counters_.unpaired_rgb;
        counters_.forced += forced ? 1 : 0;
        return d;
    }
    constexpr PairDecision drop_nir(bool forced)
    {
        PairDecision d{PairDecision::Kind::unpaired_nir, 0, nir_.items[0].id, 0, nir_.items[0].t, forced};
        nir_.erase(0);
        ++counters_.unpaired_nir;
        counters_.forced += forced ? 1 : 0;
        return d;
    }

    std::int64_t tolerance_ns_;
    Queue rgb_;
    Queue nir_;
    bool have_paired_nir_ = false;
    std::int64_t last_paired_nir_t_ = std::numeric_limits<std::int64_t>::min();
    PairingCounters counters_;
};

}  // namespace stemd::drivers
