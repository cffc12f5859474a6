// Counter-based random numbers: SplitMix64 (Steele, Lea, Flood, "Fast splittable pseudorandom
// number generators", OOPSLA 2014). splitmix64(seed + i) is a pure function of the counter, so
// samples drawn in parallel are the same for any thread count and order.
#pragma once

#include <cstdint>

namespace rgbd {

/// The golden-ratio increment of the SplitMix64 stream.
inline constexpr std::uint64_t kSplitMix64Gamma = 0x9e3779b97f4a7c15ULL;

/// SplitMix64 of the counter x: x + gamma through the finaliser (a bijective 64-bit mix).
inline std::uint64_t splitmix64(std::uint64_t x) {
    x += kSplitMix64Gamma;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

/// The next value of the SplitMix64 stream whose state is `state`, which it advances.
inline std::uint64_t splitmix64_next(std::uint64_t& state) {
    const std::uint64_t value = splitmix64(state);
    state += kSplitMix64Gamma;
    return value;
}

/// Uniform in [0, 1) from the 53 high bits of a random 64-bit word.
inline double unit_interval(std::uint64_t bits) {
    return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

}  // namespace rgbd
