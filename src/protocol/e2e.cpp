#include "stemd/protocol/e2e.hpp"

#include <algorithm>

#include "stemd/protocol/crc8.hpp"

namespace stemd::protocol {

std::uint8_t e2e_crc(std::uint16_t data_id, std::span<const std::uint8_t, 8> data)
{
    const std::array<std::uint8_t, 2> id{static_cast<std::uint8_t>(data_id & 0xFF),
                                         static_cast<std::uint8_t>(data_id >> 8)};
    const std::uint8_t crc = crc8_sae_j1850(id);
    return crc8_sae_j1850(data.subspan(1), crc, false);
}

bool e2e_protect(std::uint16_t data_id, std::uint8_t counter, std::span<std::uint8_t, 8> data)
{
    if (counter > kE2eMaxCounter)
        return false;
    data[1] = static_cast<std::uint8_t>((data[1] & 0xF0) | counter);
    data[0] = e2e_crc(data_id, data);
    return true;
}

bool e2e_crc_ok(std::uint16_t data_id, std::span<const std::uint8_t, 8> data)
{
    return e2e_crc(data_id, data) == data[0];
}

std::string_view to_string(E2eStatus s)
{
    switch (s) {
    case E2eStatus::Initial: return "initial";
    case E2eStatus::Ok: return "ok";
    case E2eStatus::OkSomeLost: return "ok_some_lost";
    case E2eStatus::Repeated: return "repeated";
    case E2eStatus::WrongSequence: return "wrong_sequence";
    case E2eStatus::WrongCrc: return "wrong_crc";
    }
    return "?";
}

E2eChecker::E2eChecker(std::uint16_t data_id, std::uint8_t max_delta_counter)
    : data_id_(data_id), max_delta_(std::clamp<std::uint8_t>(max_delta_counter, 1, kE2eMaxCounter))
{
}

E2eStatus E2eChecker::check(std::span<const std::uint8_t, 8> data)
{
    E2eStatus status;
    const std::uint8_t counter = e2e_counter_of(data);
    if (!e2e_crc_ok(data_id_, data)) {
        status = E2eStatus::WrongCrc;
    } else if (counter > kE2eMaxCounter) {
        status = E2eStatus::WrongSequence;
    } else {
        if (!synced_) {
            status = E2eStatus::Initial;
            synced_ = true;
        } else {
            const int delta = (counter + kE2eCounterModulo - last_counter_) % kE2eCounterModulo;
            if (delta == 0) {
                status = E2eStatus::Repeated;
            } else if (delta == 1) {
                status = E2eStatus::Ok;
            } else if (delta <= max_delta_) {
                status = E2eStatus::OkSomeLost;
                lost_ += static_cast<std::uint64_t>(delta - 1);
            } else {
                status = E2eStatus::WrongSequence;
            }
        }
        last_counter_ = counter;
    }
    ++counts_[static_cast<std::size_t>(status)];
    return status;
}

std::uint64_t E2eChecker::accepted() const
{
    return count(E2eStatus::Initial) + count(E2eStatus::Ok) + count(E2eStatus::OkSomeLost);
}

std::uint64_t E2eChecker::rejected() const
{
    return count(E2eStatus::Repeated) + count(E2eStatus::WrongSequence) + count(E2eStatus::WrongCrc);
}

}  // namespace stemd::protocol
