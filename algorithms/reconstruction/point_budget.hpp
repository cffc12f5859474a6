// The point budget of the surface reconstruction (docs/algorithms.md §14): a cloud denser than
// the budget is voxel-downsampled to fit it. Internal to algorithms/reconstruction (not
// installed).
#pragma once

#include <cstddef>

#include "toolkit/point_cloud.hpp"

namespace rgbd::reconstruction::internal {

/// Voxel-downsamples until at most max_points remain: the first voxel of ŝ sqrt(n / max) x 1.1^k
/// (k = 0, 1, ...) whose grid fits, in `voxel` (metres; 0 when the cloud fits as it is). The
/// voxel is chosen by counting occupied voxels on the bare coordinates, starting from the step
/// one count at the first voxel predicts (a surface's count falls as 1 / voxel^2) and going
/// back while the step before fits; only the chosen one down-samples the cloud with all its
/// properties. Throws AlgorithmError when 60 steps do not fit.
PointCloud bounded(const PointCloud& cloud, std::size_t max_points, double spacing, double& voxel);

}  // namespace rgbd::reconstruction::internal
