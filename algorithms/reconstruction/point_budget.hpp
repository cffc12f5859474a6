// The point budget of the surface reconstruction (docs/algorithms.md §14): a cloud denser than
// the budget is voxel-downsampled to fit it. Internal to algorithms/reconstruction (not
// installed).
#pragma once

#include <cstddef>

#include "toolkit/point_cloud.hpp"

namespace rgbd::reconstruction::internal {

/// Voxel-downsamples until at most max_points remain (voxel grows from ŝ sqrt(n / max) by 10%
/// steps). The voxel is chosen by counting occupied voxels on the bare coordinates; only the
/// chosen one down-samples the cloud with all its properties.
PointCloud bounded(const PointCloud& cloud, std::size_t max_points, double spacing, double& voxel);

}  // namespace rgbd::reconstruction::internal
