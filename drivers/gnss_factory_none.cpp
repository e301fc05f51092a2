// make_gpsd_source in a build without libgps.
#include "stemd/drivers/gnss_factory.hpp"

namespace stemd::drivers {

std::unique_ptr<GnssSource> make_gpsd_source(const GnssSpec&, std::shared_ptr<spdlog::logger>, std::string& error)
{
    error = "gnss.source gpsd: this stemd was built without libgps (apt install libgps-dev, rebuild)";
    return nullptr;
}

}  // namespace stemd::drivers
