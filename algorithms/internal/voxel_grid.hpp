// The voxel grid the voxel-grid samplers share (sampling::voxel_downsample, holes::thin_points):
// points keyed by their voxel (21 bits per axis, grid anchored at a corner `lo`), sorted so
// that a voxel's points are consecutive, with the voxel's centre and the point of a voxel
// nearest to a target. Internal: not a public header.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace rgbd::internal {

/// Bits per axis of a voxel key: a grid has at most 2^21 voxels along an axis.
inline constexpr int kVoxelKeyBits = 21;
inline constexpr std::uint64_t kVoxelAxisMax = (std::uint64_t{1} << kVoxelKeyBits) - 1;

/// (voxel key, index into the points) pairs.
using VoxelKeyed = std::vector<std::pair<std::uint64_t, std::uint32_t>>;

/// Keys every point of `xyz` by its voxel on the grid of edge `edge` (metres) anchored at `lo`
/// and sorts the pairs (by key, then index): the points of a voxel are consecutive, in input
/// order, and the order does not depend on the thread count. Voxel coordinates outside
/// [0, 2^21 - 1] are clamped to it: callers keep the points' extent inside the grid.
/// `keyed` is resized and reused.
inline void sort_by_voxel(const std::vector<Eigen::Vector3d>& xyz, const Eigen::Vector3d& lo,
                          double edge, VoxelKeyed& keyed) {
    const std::size_t n = xyz.size();
    keyed.resize(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const Eigen::Vector3d c = (xyz[i] - lo) / edge;
            const auto axis = [](double v) {
                return std::min(static_cast<std::uint64_t>(std::max(v, 0.0)), kVoxelAxisMax);
            };
            keyed[i] = {
                axis(c.x()) | axis(c.y()) << kVoxelKeyBits | axis(c.z()) << (2 * kVoxelKeyBits),
                static_cast<std::uint32_t>(i)};
        }
    });
    tbb::parallel_sort(keyed.begin(), keyed.end());
}

/// Where each voxel's run starts in sorted `keyed`, and keyed.size() last: voxel g holds
/// keyed[starts[g] .. starts[g + 1]).
inline std::vector<std::size_t> voxel_starts(const VoxelKeyed& keyed) {
    std::vector<std::size_t> starts;
    for (std::size_t i = 0; i < keyed.size(); ++i)
        if (i == 0 || keyed[i].first != keyed[i - 1].first) starts.push_back(i);
    starts.push_back(keyed.size());
    return starts;
}

/// Centre of the voxel `key` of the grid of edge `edge` anchored at `lo`.
inline Eigen::Vector3d voxel_centre(std::uint64_t key, const Eigen::Vector3d& lo, double edge) {
    return lo +
           edge * Eigen::Vector3d(static_cast<double>(key & kVoxelAxisMax) + 0.5,
                                  static_cast<double>(key >> kVoxelKeyBits & kVoxelAxisMax) + 0.5,
                                  static_cast<double>(key >> (2 * kVoxelKeyBits)) + 0.5);
}

/// Of the points keyed[begin .. end) of one voxel, the index of the one nearest to `target`
/// (ties: the lower index, since a voxel's run is sorted by index).
inline std::uint32_t nearest_in_voxel(const VoxelKeyed& keyed, std::size_t begin, std::size_t end,
                                      const std::vector<Eigen::Vector3d>& xyz,
                                      const Eigen::Vector3d& target) {
    std::uint32_t best = keyed[begin].second;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t k = begin; k < end; ++k) {
        const double d = (xyz[keyed[k].second] - target).squaredNorm();
        if (d < best_d) {
            best_d = d;
            best = keyed[k].second;
        }
    }
    return best;
}

}  // namespace rgbd::internal
