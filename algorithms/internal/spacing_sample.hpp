// The two halves of sampling::robust_spacing() around its nearest-neighbour search, for
// callers inside algorithms/ that already know the points' nearest-neighbour distances and
// must reproduce the estimate exactly (density_outliers.cpp). Internal: not a public header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace rgbd::internal {

/// The query sample of robust_spacing(): min(sample, n) indices of [0, n), drawn without
/// replacement with `seed` (all of them, in order, when n <= sample).
std::vector<std::uint32_t> spacing_sample(std::size_t n, std::size_t sample, std::uint64_t seed);

/// The median robust_spacing() takes of the sample's nearest-neighbour distances (mean of the
/// two middle values for an even count; 0 when empty). Reorders `dist`.
double spacing_median(std::vector<double>& dist);

}  // namespace rgbd::internal
