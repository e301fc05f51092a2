// frames.csv as the replay, stemd-detect and stemd-eval read it: any text
// reads as a recording or is refused with the line that is wrong.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "stemd/io/recording.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    // One directory per process, rewritten per input (tmpfs when /dev/shm exists).
    static const std::filesystem::path dir = [] {
        const std::filesystem::path base =
            std::filesystem::exists("/dev/shm") ? "/dev/shm" : std::filesystem::temp_directory_path();
        auto d = base / ("stemd-fuzz-recording-" + std::to_string(getpid()));
        std::filesystem::create_directories(d);
        return d;
    }();
    {
        std::ofstream csv(dir / "frames.csv", std::ios::binary | std::ios::trunc);
        csv.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    }
    std::string error;
    (void)stemd::io::read_recording(dir, error);
    return 0;
}
