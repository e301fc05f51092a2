// GpioLines for tests: an enable input and encoder ticks the test sets, and
// a trigger output that counts its pulses (atomics: the daemon's threads
// call it).
#pragma once

#include <atomic>

#include "stemd/drivers/gpio_lines.hpp"

namespace stemd::test {

class FakeGpioLines final : public drivers::GpioLines {
public:
    explicit FakeGpioLines(bool with_trigger = false) : with_trigger_(with_trigger) {}
    std::string_view name() const override { return "fake-gpio"; }
    bool enabled() const override { return enable.load(); }
    bool wait_change(bool, std::int64_t) override { return false; }
    bool has_trigger() const override { return with_trigger_; }
    bool set_trigger(bool) override { return with_trigger_; }
    bool pulse(std::uint32_t width_us) override
    {
        last_width_us.store(width_us);
        pulses.fetch_add(1);
        return with_trigger_ && trigger_works.load();
    }
    drivers::EncoderMode encoder_mode() const override { return encoder_mode_value; }
    drivers::EncoderReading encoder() const override { return {.ticks = ticks.load(), .direction = 1}; }
    drivers::GpioCounters counters() const override { return {}; }

    std::atomic<bool> enable{true};
    std::atomic<std::uint64_t> pulses{0};            // pulse() calls
    std::atomic<bool> trigger_works{true};           // false: pulse() fails (lines down)
    std::atomic<std::uint32_t> last_width_us{0};
    std::atomic<std::int64_t> ticks{0};
    drivers::EncoderMode encoder_mode_value = drivers::EncoderMode::none;

private:
    bool with_trigger_;
};

}  // namespace stemd::test
