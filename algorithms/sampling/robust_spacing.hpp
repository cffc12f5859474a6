// Robust point spacing ŝ: the median, over a random sample of points, of the distance to the
// nearest other point (docs/algorithms.md, notation). Every length threshold after cloud generation
// is a multiple of it. Source: the median-of-NN-distances estimator; CGAL compute_average_spacing
// is the mean-based peer (less robust to duplicates and outliers).
// See also: algorithms/sampling/voxel_downsample.hpp, algorithms/internal/kd_tree.hpp.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "toolkit/point_cloud.hpp"

namespace rgbd::sampling {

/// Robust spacing ŝ of a point set, in metres.
/// @param points  at least 2 points (removed points are ignored).
/// @param sample  number of query points drawn without replacement (default 10000); all points
///                are used when the set is smaller. The neighbour is searched among all points.
/// @param seed    seed of the sample (same seed, same result, for any thread count).
/// Throws InputError when fewer than 2 points are present or a coordinate is not finite.
/// Exact duplicates count as distance 0 (the median stays robust to a few of them).
double robust_spacing(const PointSet& points, std::size_t sample = 10000, std::uint64_t seed = 0);

/// The same estimator over a contiguous array of points (no copy into a PointSet): equal to
/// robust_spacing() of a PointSet holding these points in this order.
double robust_spacing(const std::vector<Eigen::Vector3d>& points, std::size_t sample = 10000,
                      std::uint64_t seed = 0);

/// ŝ of a set of views: the median (upper median for an even count) over the views of
/// robust_spacing(view.points, sample); views with fewer than 2 points are skipped. Returns 0
/// when no view has 2 points.
double median_view_spacing(const std::vector<const PointCloud*>& views, std::size_t sample = 2000);

}  // namespace rgbd::sampling
