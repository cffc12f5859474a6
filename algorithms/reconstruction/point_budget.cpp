#include "algorithms/reconstruction/point_budget.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "algorithms/sampling/voxel_downsample.hpp"
#include "toolkit/error.hpp"
#include "toolkit/types.hpp"

namespace rgbd::reconstruction::internal {

namespace {

/// Whether more than `limit` voxels of edge `voxel` on the grid of sampling::voxel_downsample
/// (anchored at the minimum corner `lo`) hold a point: whether its output would have more than
/// `limit` points, from the coordinates alone. The keys are computed in parallel, then the
/// distinct ones go into an open-addressing set of about 4 * limit slots, and the scan stops at
/// the (limit + 1)-th: where sorting every point's key took a quarter of a second at every try.
bool more_voxels_than(const std::vector<Eigen::Vector3d>& xyz, const Eigen::Vector3d& lo,
                      double voxel, std::size_t limit) {
    std::vector<std::uint64_t> keys(xyz.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, xyz.size(), 16384),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const Eigen::Vector3d c = ((xyz[i] - lo) / voxel).array().floor();
                              keys[i] = (static_cast<std::uint64_t>(c.x()) & 0x1FFFFF) |
                                        ((static_cast<std::uint64_t>(c.y()) & 0x1FFFFF) << 21) |
                                        ((static_cast<std::uint64_t>(c.z()) & 0x1FFFFF) << 42);
                          }
                      });
    std::size_t slots = 64;
    while (slots < 4 * (limit + 1)) slots *= 2;
    const std::size_t mask = slots - 1;
    // Key + 1 in a slot; 0 marks an empty one.
    std::vector<std::uint64_t> set(slots, 0);
    std::size_t distinct = 0;
    // Consecutive points (a depth image's row) mostly share a voxel: the set is not probed again.
    std::uint64_t previous = ~std::uint64_t(0);
    for (const std::uint64_t key : keys) {
        if (key == previous) continue;
        previous = key;
        // Fibonacci hashing of the key into the table's slots, then linear probing.
        std::size_t slot = static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & mask;
        while (set[slot] != 0 && set[slot] != key + 1) slot = (slot + 1) & mask;
        if (set[slot] == 0) {
            set[slot] = key + 1;
            if (++distinct > limit) return true;
        }
    }
    return false;
}

}  // namespace

PointCloud bounded(const PointCloud& cloud, std::size_t max_points, double spacing, double& voxel) {
    voxel = 0.0;
    if (max_points == 0 || cloud.size() <= max_points) return cloud;
    std::vector<Eigen::Vector3d> xyz;
    xyz.reserve(cloud.size());
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    for (auto idx : cloud.points) {
        xyz.push_back(to_eigen(cloud.points.point(idx)));
        lo = lo.cwiseMin(xyz.back());
    }
    voxel = spacing * std::sqrt(static_cast<double>(cloud.size()) / max_points);
    for (int attempt = 0; attempt < 60; ++attempt, voxel *= 1.1) {
        if (more_voxels_than(xyz, lo, voxel, max_points)) continue;
        PointCloud down = sampling::voxel_downsample(cloud, voxel);
        if (down.size() <= max_points) return down;
    }
    throw AlgorithmError("reconstruction: view " + std::to_string(cloud.view.id) +
                         ": cannot down-sample to the point budget");
}

}  // namespace rgbd::reconstruction::internal
