#include "random.hpp"

namespace stemd::synth {

std::uint64_t mix(std::uint64_t a, std::uint64_t b)
{
    std::uint64_t state = a;
    state = splitmix64(state) ^ b;
    return splitmix64(state);
}

Rng make_stream(const Options& options, int frame_index, Stream stream)
{
    std::uint64_t key = mix(options.seed, static_cast<std::uint64_t>(options.preset) + 1);
    key = mix(key, static_cast<std::uint64_t>(frame_index));
    return Rng(mix(key, static_cast<std::uint64_t>(stream)));
}

}  // namespace stemd::synth
