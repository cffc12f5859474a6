// Voxel-grid down-sampling: one point per occupied cubic voxel (centroid of its points,
// averaged colour and normal). Source: the voxel filter of PCL (VoxelGrid) and Open3D
// (voxel_down_sample); CGAL grid_simplify_point_set keeps an input point instead of the centroid.
// See also: algorithms/sampling/robust_spacing.hpp (choose the voxel as a multiple of ŝ),
// docs/algorithms.md §6 step 1.
#pragma once

#include "toolkit/point_cloud.hpp"

namespace rgbd::sampling {

/// Returns a new cloud with one point per occupied voxel of edge `voxel_m` (metres, > 0,
/// grid anchored at the minimum corner of the bounding box):
/// - position = centroid of the voxel's points;
/// - colour (if present) = rounded mean colour; normal (if present) = renormalised mean normal
///   (the normal of the representative when the mean vanishes);
/// - every other property (pixel, view, flags, ...) = that of the input point nearest to the
///   centroid (the representative; ties go to the lower index).
/// Output order is deterministic (by voxel key) and independent of the thread count.
/// View metadata is copied; the grid is cleared (the result is no longer organised).
/// Throws InputError when voxel_m is not positive/finite, a coordinate is not finite, or the
/// grid would need more than 2^21 voxels along an axis.
PointCloud voxel_downsample(const PointCloud& cloud, double voxel_m);

}  // namespace rgbd::sampling
