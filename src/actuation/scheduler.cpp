#include "stemd/actuation/scheduler.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "stemd/actuation/fire_lag.hpp"
#include "stemd/base/enum_names.hpp"

namespace stemd::actuation {

namespace {

constexpr base::EnumName<TreatPolicy> kTreatPolicies[]{{TreatPolicy::weeds_only, "weeds_only"}, {TreatPolicy::all, "all"}};
constexpr base::EnumName<ScheduleOutcome> kScheduleOutcomes[]{
    {ScheduleOutcome::send, "send"}, {ScheduleOutcome::policy, "policy"}, {ScheduleOutcome::no_tool, "no_tool"},
    {ScheduleOutcome::disabled, "disabled"}, {ScheduleOutcome::not_ready, "not_ready"},
    {ScheduleOutcome::deadline_miss, "deadline_miss"}};

}  // namespace

std::string_view to_string(TreatPolicy p) { return base::name_of(kTreatPolicies, p); }
std::optional<TreatPolicy> parse_treat_policy(std::string_view s) { return base::value_of(kTreatPolicies, s); }
std::string_view to_string(ScheduleOutcome o) { return base::name_of(kScheduleOutcomes, o); }

std::optional<Scheduler> Scheduler::make(std::span<const ToolSpec> tools, const SchedulerParams& params,
                                         std::string_view* error)
{
    auto fail = [&](std::string_view why) -> std::optional<Scheduler> {
        if (error)
            *error = why;
        return std::nullopt;
    };
    if (tools.empty())
        return fail("no tools");
    if (tools.size() > kMaxTools)
        return fail("more than 16 tools");
    for (std::size_t i = 0; i < tools.size(); ++i) {
        const ToolSpec& t = tools[i];
        if (t.id > protocol::kMaxToolId)
            return fail("tool id above 15");
        for (std::size_t j = 0; j < i; ++j)
            if (tools[j].id == t.id)
                return fail("repeated tool id");
        if (!std::isfinite(t.offset_mm))
            return fail("tool offset_mm not finite");
        if (!std::isfinite(t.y_min_mm) || !std::isfinite(t.y_max_mm) || !(t.y_min_mm < t.y_max_mm))
            return fail("tool span empty or not finite (y_min_mm < y_max_mm)");
        if (t.lanes < 1 || t.lanes > protocol::kMaxLane + 1)
            return fail("tool lanes outside 1..16");
        if (!std::isfinite(t.latency_ms) || t.latency_ms < 0 || t.latency_ms > kMaxLatencyMs)
            return fail("tool latency_ms outside 0..1000");
        if (t.learn_latency &&
            !(t.latency_min_ms >= 0 && t.latency_min_ms <= t.latency_max_ms && t.latency_max_ms <= kMaxLatencyMs))
            return fail("tool latency_min_ms .. latency_max_ms not within 0..1000 and ordered");
    }
    const auto finite_nonneg = [](double v) { return std::isfinite(v) && v >= 0; };
    if (!finite_nonneg(params.lead_ms) || !finite_nonneg(params.send_budget_ms))
        return fail("lead_ms and send_budget_ms must be finite and >= 0");
    if (!finite_nonneg(params.standing_speed_mm_per_s) || !finite_nonneg(params.standing_deadline_ms))
        return fail("standing_speed_mm_per_s and standing_deadline_ms must be finite and >= 0");

    Scheduler s;
    for (std::size_t i = 0; i < tools.size(); ++i)
        s.tools_[i] = tools[i];
    s.n_tools_ = tools.size();
    s.params_ = params;
    if (error)
        *error = {};
    return s;
}

bool Scheduler::set_latency_ms(std::uint8_t tool_id, double latency_ms) noexcept
{
    if (!std::isfinite(latency_ms))
        return false;
    for (std::size_t i = 0; i < n_tools_; ++i)
        if (tools_[i].id == tool_id) {
            tools_[i].latency_ms = std::clamp(latency_ms, 0.0, kMaxLatencyMs);
            return true;
        }
    return false;
}

ScheduleDecision Scheduler::schedule(const Target& target, const ScheduleNow& now) noexcept
{
    ++counters_.scheduled;
    ScheduleDecision dec;
    dec.command.target_id = static_cast<std::uint16_t>(target.target_id & protocol::kMaxTargetId);
    dec.command.plant_class = target.plant_class;

    // 1. Policy.
    if (params_.policy == TreatPolicy::weeds_only && target.plant_class != PlantClass::Weed) {
        dec.outcome = ScheduleOutcome::policy;
        ++counters_.policy;
        return dec;
    }

    // 2. A tool covering y (the first in table order; see 4 for the rest).
    const double y = target.y_mm;
    const bool position_ok = std::isfinite(y) && std::isfinite(target.s_mm) &&
                             std::abs(y) <= protocol::kMaxLateralMm + 0.5 && std::isfinite(now.odom_mm);
    std::size_t first = n_tools_;
    if (position_ok)
        for (std::size_t i = 0; i < n_tools_; ++i)
            if (y >= tools_[i].y_min_mm && y <= tools_[i].y_max_mm) {
                first = i;
                break;
            }
    if (first == n_tools_) {
        dec.outcome = ScheduleOutcome::no_tool;
        ++counters_.no_tool;
        return dec;
    }
    dec.command.lateral_mm = static_cast<std::int16_t>(
        std::clamp<long>(std::lround(y), -static_cast<long>(protocol::kMaxLateralMm), protocol::kMaxLateralMm));

    const auto fill = [&](const ToolSpec& t) {
        dec.command.tool_id = t.id;
        const double width = (t.y_max_mm - t.y_min_mm) / t.lanes;
        const double f = std::floor((y - t.y_min_mm) / width);
        const long lane = std::clamp<long>(static_cast<long>(f), 0, t.lanes - 1);
        dec.command.lane = static_cast<std::uint8_t>(lane);
        dec.aim_odom_mm = target.s_mm + t.offset_mm;
        dec.lead_mm = compensation_mm(now.speed_mm_per_s, t.latency_ms, params_.standing_speed_mm_per_s);
        dec.fire_odom_mm = dec.aim_odom_mm - dec.lead_mm;
        // The 32-bit odometer scale (encode truncates to 18 bits): modulo 2^32.
        const double wrapped = std::fmod(std::round(dec.fire_odom_mm), 4294967296.0);
        dec.command.fire_odom_mm =
            static_cast<std::uint32_t>(static_cast<std::int64_t>(wrapped < 0 ? wrapped + 4294967296.0 : wrapped));
    };
    fill(tools_[first]);

    // 3. Enable input.
    if (!now.enabled) {
        dec.outcome = ScheduleOutcome::disabled;
        ++counters_.disabled;
        return dec;
    }

    // 4. A covering tool that is ready (the first in table order).
    const auto usable = [&](const ToolSpec& t) {
        return y >= t.y_min_mm && y <= t.y_max_mm && (now.tools_ready_mask >> t.id & 1U) != 0;
    };
    std::size_t first_ready = first;
    while (first_ready < n_tools_ && !usable(tools_[first_ready]))
        ++first_ready;
    if (first_ready == n_tools_) {
        dec.outcome = ScheduleOutcome::not_ready;
        ++counters_.not_ready;
        return dec;
    }
    first = first_ready;

    // 5. Deadline: the first ready covering tool that can be on time.
    const double v = std::isfinite(now.speed_mm_per_s) ? now.speed_mm_per_s : 0.0;
    const bool standing = v <= params_.standing_speed_mm_per_s;
    const double need_ms = params_.lead_ms + params_.send_budget_ms;
    for (std::size_t i = first; i < n_tools_; ++i) {
        const ToolSpec& t = tools_[i];
        if (!usable(t))
            continue;
        fill(t);
        const double d = dec.fire_odom_mm - now.odom_mm;
        if (d < 0) {
            dec.time_to_arrival_ms = standing ? std::numeric_limits<double>::infinity() : d / v * 1000.0;
            continue;
        }
        if (standing) {
            dec.time_to_arrival_ms = std::numeric_limits<double>::infinity();
            dec.deadline_ns = now.now_ns + static_cast<std::int64_t>(params_.standing_deadline_ms * 1e6);
            dec.outcome = ScheduleOutcome::send;
            ++counters_.sent;
            return dec;
        }
        dec.time_to_arrival_ms = d / v * 1000.0;
        if (d * 1000.0 < need_ms * v)
            continue;
        // On the bus by arrival - lead_ms (>= now + send_budget_ms).
        const double slack_ms = std::max(dec.time_to_arrival_ms - params_.lead_ms, 0.0);
        const double slack_ns = std::min(slack_ms * 1e6, 9.0e18);
        dec.deadline_ns = now.now_ns + static_cast<std::int64_t>(slack_ns);
        dec.outcome = ScheduleOutcome::send;
        ++counters_.sent;
        return dec;
    }
    // No ready covering tool can be on time: report the first one.
    fill(tools_[first]);
    {
        const double d = dec.fire_odom_mm - now.odom_mm;
        const double d_aim = dec.aim_odom_mm - now.odom_mm;
        if (dec.lead_mm > 0 && d_aim >= 0 && (standing || d_aim * 1000.0 >= need_ms * v)) {
            dec.compensation_miss = true;
            ++counters_.compensation_misses;
        }
        dec.time_to_arrival_ms = standing ? (d < 0 ? -std::numeric_limits<double>::infinity()
                                                   : std::numeric_limits<double>::infinity())
                                          : d / v * 1000.0;
    }
    dec.outcome = ScheduleOutcome::deadline_miss;
    ++counters_.deadline_misses;
    return dec;
}

}  // namespace stemd::actuation
