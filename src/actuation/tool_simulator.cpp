#include "stemd/actuation/tool_simulator.hpp"

#include <cmath>

namespace stemd::actuation {

namespace {

// The 32-bit odometer scale of an unwrapped reading.
std::uint32_t raw_of(double odom_mm)
{
    const double wrapped = std::fmod(std::round(odom_mm), 4294967296.0);
    return static_cast<std::uint32_t>(static_cast<std::int64_t>(wrapped < 0 ? wrapped + 4294967296.0 : wrapped));
}

}  // namespace

ToolSimulator::ToolSimulator(double delay_ms) noexcept : delay_ms_(delay_ms > 0 ? delay_ms : 0) {}

bool ToolSimulator::command(const protocol::TargetCommand& target, double odom_mm) noexcept
{
    ++counters_.commands;
    const double fire_mm = odom_mm + protocol::fire_distance_mm(target.fire_odom_mm, raw_of(odom_mm));
    if (fire_mm < odom_mm) {
        ++counters_.late;
        return false;
    }
    for (Pending& p : pending_)
        if (!p.used) {
            p = Pending{true, false, target, fire_mm, 0};
            return true;
        }
    ++counters_.full;
    return false;
}

std::span<const protocol::ToolFired> ToolSimulator::advance(std::int64_t t_ns, double odom_mm) noexcept
{
    std::size_t n = 0;
    if (!have_sample_) {
        // The first sample only says where the odometer is.
        have_sample_ = true;
        last_t_ns_ = t_ns;
        last_odom_mm_ = odom_mm;
        return {fired_.data(), 0};
    }
    if (t_ns <= last_t_ns_)
        return {fired_.data(), 0};   // not after the last sample: nothing to interpolate
    const double t0 = static_cast<double>(last_t_ns_), t1 = static_cast<double>(t_ns);
    const double o0 = last_odom_mm_, o1 = odom_mm;
    const double delay_ns = delay_ms_ * 1e6;
    for (Pending& p : pending_) {
        if (!p.used)
            continue;
        if (!p.triggered && o1 >= p.fire_mm) {
            // Where between the samples the odometer reached the point.
            const double f = o1 > o0 && p.fire_mm > o0 ? (p.fire_mm - o0) / (o1 - o0) : 0.0;
            p.trigger_t_ns = t0 + f * (t1 - t0);
            p.triggered = true;
        }
        if (!p.triggered || p.trigger_t_ns + delay_ns > t1)
            continue;
        const double strike_t = p.trigger_t_ns + delay_ns;
        const double f = strike_t > t0 ? (strike_t - t0) / (t1 - t0) : 0.0;
        protocol::ToolFired out;
        out.target_id = p.command.target_id;
        out.tool_id = p.command.tool_id;
        out.lane = p.command.lane;
        out.fired_odom_mm = raw_of(o0 + f * (o1 - o0));
        fired_[n++] = out;
        ++counters_.fired;
        p.used = false;
    }
    last_t_ns_ = t_ns;
    last_odom_mm_ = odom_mm;
    return {fired_.data(), n};
}

}  // namespace stemd::actuation
