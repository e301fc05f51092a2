#include "stemd/runtime/plant_map.hpp"

#include <cerrno>
#include <cstring>

namespace stemd::runtime {

namespace {

constexpr std::size_t kBufferBytes = 1 << 20;

}  // namespace

std::string_view to_string(MapReason r)
{
    switch (r) {
    case MapReason::sent: return "sent";
    case MapReason::policy: return "policy";
    case MapReason::no_tool: return "no_tool";
    case MapReason::disabled: return "disabled";
    case MapReason::deadline_miss: return "deadline_miss";
    case MapReason::bus_deadline: return "bus_deadline";
    case MapReason::bus_error: return "bus_error";
    case MapReason::no_odometry: return "no_odometry";
    case MapReason::unconfirmed: return "unconfirmed";
    case MapReason::pending: return "pending";
    }
    return "?";
}

PlantMap::PlantMap(std::shared_ptr<spdlog::logger> log) : log_(std::move(log)) {}

PlantMap::~PlantMap()
{
    close();
}

bool PlantMap::open(const std::filesystem::path& path)
{
    path_ = path;
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) {
        const int err = errno;
        log_->error("{}: cannot create the plant map: {} (errno {})", path.string(), std::strerror(err), err);
        return false;
    }
    buffer_ = std::make_unique<char[]>(kBufferBytes);
    std::setvbuf(f, buffer_.get(), _IOFBF, kBufferBytes);
    file_.reset(f);
    return true;
}

bool PlantMap::write(const actuation::RetiredTrack& t, const MapEntry& e)
{
    if (!file_)
        return true;
    const bool treated = e.reason == MapReason::sent;
    int n = std::fprintf(file_.get(),
                         "{\"id\":%d,\"s_mm\":%.1f,\"y_mm\":%.1f,\"class\":\"%.*s\",\"leaves\":%u,\"sightings\":%u,"
                         "\"first_frame\":%llu,\"last_frame\":%llu,\"treated\":%s,\"reason\":\"%.*s\"",
                         t.emitted ? static_cast<int>(t.target_id) : -1, t.s_mm, t.y_mm,
                         static_cast<int>(to_string(t.plant_class).size()), to_string(t.plant_class).data(),
                         static_cast<unsigned>(t.leaves), static_cast<unsigned>(t.sightings),
                         static_cast<unsigned long long>(t.first_seq), static_cast<unsigned long long>(t.last_seq),
                         treated ? "true" : "false", static_cast<int>(to_string(e.reason).size()),
                         to_string(e.reason).data());
    if (n >= 0 && e.has_tool)
        n = std::fprintf(file_.get(), ",\"tool\":%u,\"lane\":%u,\"fire_odom_mm\":%.1f", static_cast<unsigned>(e.tool),
                         static_cast<unsigned>(e.lane), e.fire_odom_mm);
    if (n >= 0)
        n = std::fputs("}\n", file_.get());
    if (n < 0) {
        if (!failed_) {
            const int err = errno;
            log_->error("{}: plant map write failed: {} (errno {})", path_.string(), std::strerror(err), err);
        }
        failed_ = true;
        return false;
    }
    ++lines_;
    return true;
}

bool PlantMap::close()
{
    if (!file_)
        return !failed_;
    std::FILE* f = file_.release();
    if (std::fclose(f) != 0 && !failed_) {
        const int err = errno;
        log_->error("{}: cannot write the plant map: {} (errno {})", path_.string(), std::strerror(err), err);
        failed_ = true;
    }
    buffer_.reset();
    return !failed_;
}

}  // namespace stemd::runtime
