// Counter-based random numbers for the synthetic harness: every draw is a pure function of
// (seed, stream, index), so rendered noise is identical for a seed whatever the number of
// threads and the order in which pixels are processed. Source: SplitMix64 finaliser
// (Steele, Lea, Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014).
// See also: noise.hpp (per-pixel noise), synthesize.hpp (per-sensor seeds).
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>

#include "toolkit/random.hpp"

namespace rgbd::synth {

/// Derives an independent seed from a parent seed and up to three integers (sensor, frame, ...).
inline std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t a, std::uint64_t b = 0,
                                 std::uint64_t c = 0) {
    return splitmix64(
        splitmix64(splitmix64(seed ^ splitmix64(a + 1)) ^ splitmix64(b + 0x51ed27ULL)) ^
        splitmix64(c + 0x2545fULL));
}

/// A deterministic random stream addressed by (seed, stream, index): draw k of an element.
class CounterRandom {
public:
    explicit CounterRandom(std::uint64_t seed) : seed_(seed) {}

    /// 64 random bits for element `index` in stream `stream`.
    std::uint64_t bits(std::uint64_t stream, std::uint64_t index) const {
        return splitmix64(splitmix64(seed_ ^ (stream * 0xd1342543de82ef95ULL)) + index);
    }
    /// Uniform in [0, 1) (53 bits).
    double uniform(std::uint64_t stream, std::uint64_t index) const {
        return unit_interval(bits(stream, index));
    }
    /// Standard normal (Box-Muller on two sub-streams).
    double normal(std::uint64_t stream, std::uint64_t index) const {
        const double u1 = uniform(stream * 2 + 1000003, index);
        const double u2 = uniform(stream * 2 + 1000004, index);
        const double r = std::sqrt(-2.0 * std::log(1.0 - u1));  // 1 - u1 in (0, 1]
        return r * std::cos(2.0 * std::numbers::pi * u2);
    }

private:
    std::uint64_t seed_;
};

}  // namespace rgbd::synth
