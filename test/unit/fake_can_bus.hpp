// A CanBus for tests: records what is sent (with deadlines) and delivers
// queued frames to receive(). Not thread-safe: read it after the thread
// driving it has been joined.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <vector>

#include "stemd/drivers/can_bus.hpp"

namespace stemd::test {

class FakeCanBus final : public drivers::CanBus {
public:
    std::string_view name() const override { return "fake"; }
    using drivers::CanBus::send;
    drivers::SendResult send(const protocol::CanFrame& frame, std::int64_t deadline_ns, drivers::SendGate gate) override
    {
        if (before_write)
            before_write(frame);
        if (!gate.open())
            return drivers::SendResult::withdrawn;
        if (fail_id && frame.id == *fail_id)
            return drivers::SendResult::error;
        sent.push_back(frame);
        deadlines.push_back(deadline_ns);
        return drivers::SendResult::sent;
    }
    using drivers::CanBus::receive;
    bool receive(protocol::CanFrame& out, std::int64_t, std::int64_t& t_rx_ns) override
    {
        if (inbox.empty())
            return false;
        out = inbox.front();
        inbox.pop_front();
        t_rx_ns = inbox_t_rx_ns.empty() ? base::monotonic_ns() : inbox_t_rx_ns.front();
        if (!inbox_t_rx_ns.empty())
            inbox_t_rx_ns.pop_front();
        return true;
    }
    drivers::CanBusCounters counters() const override { return {}; }

    std::vector<protocol::CanFrame> sent;
    std::vector<std::int64_t> deadlines;
    std::deque<protocol::CanFrame> inbox;
    // Receive times of the inbox's first frames; the others get the read time.
    std::deque<std::int64_t> inbox_t_rx_ns;
    std::optional<std::uint32_t> fail_id;   // sends of this identifier fail (not recorded)
    // Runs in send() before the gate is checked: what a real bus's wait for
    // a full transmit queue lets happen (the enable input dropping).
    std::function<void(const protocol::CanFrame&)> before_write;
};

}  // namespace stemd::test
