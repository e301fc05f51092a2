// Our own random streams: splitmix64 keyed on (seed, preset, frame,
// purpose), turned into numbers by integer or IEEE-exact arithmetic, so that
// frames are byte-identical on every CPU and run.
#pragma once

#include <cstdint>

#include "stemd/synth/synth.hpp"

namespace stemd::synth {

inline std::uint64_t splitmix64(std::uint64_t& state)
{
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

// Combines two words so that nearby inputs give unrelated outputs.
std::uint64_t mix(std::uint64_t a, std::uint64_t b);

class Rng {
public:
    explicit Rng(std::uint64_t seed) : state_(seed) {}
    std::uint64_t bits() { return splitmix64(state_); }
    // [0, 1) from the top 53 bits: exact, the same everywhere.
    double uniform() { return static_cast<double>(bits() >> 11) * 0x1.0p-53; }
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    // Inclusive; the multiply-shift bias (< 2^-32) does not matter here.
    int uniform_int(int lo, int hi)
    {
        const auto n = static_cast<std::uint64_t>(hi - lo + 1);
        return lo + static_cast<int>(((bits() >> 32) * n) >> 32);
    }
    bool chance(double p) { return uniform() < p; }

private:
    std::uint64_t state_;
};

// New streams go at the end: the others' numbers key every preset's bytes.
enum class Stream : std::uint64_t { layout = 1, soil, fragments, sensor, camera };

// The stream for `stream` of generate_frame's frame `frame_index`.
Rng make_stream(const Options& options, int frame_index, Stream stream);

}  // namespace stemd::synth
