#include "algorithms/reconstruction/point_budget.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <algorithm>
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

/// The distinct voxels of edge `voxel` on the grid of sampling::voxel_downsample (anchored at
/// the minimum corner `lo`) that hold a point of `xyz`, counted up to `limit` + 1: whether its
/// output would have more than `limit` points, from the coordinates alone. The points' keys are
/// computed in parallel, 65,536 at a time, and go into an open-addressing set of about
/// 4 * limit slots; the count stops at limit + 1 (a voxel too small for the budget is refused
/// after the first part of the points, where sorting every point's key took a quarter of a
/// second at every try).
class VoxelCounter {
public:
    VoxelCounter(const std::vector<Eigen::Vector3d>& xyz, const Eigen::Vector3d& lo)
        : xyz_(xyz), lo_(lo), keys_(std::min<std::size_t>(xyz.size(), kChunk)) {}

    std::size_t count(double voxel, std::size_t limit) {
        std::size_t slots = 64;
        while (slots < 4 * (limit + 1)) slots *= 2;
        const std::size_t mask = slots - 1;
        // Key + 1 in a slot; 0 marks an empty one.
        set_.assign(slots, 0);
        std::size_t distinct = 0;
        // Consecutive points (a depth image's row) mostly share a voxel: not probed again.
        std::uint64_t previous = ~std::uint64_t(0);
        for (std::size_t begin = 0; begin < xyz_.size(); begin += kChunk) {
            const std::size_t end = std::min(xyz_.size(), begin + kChunk);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, end, 16384),
                              [&](const tbb::blocked_range<std::size_t>& r) {
                                  for (std::size_t i = r.begin(); i != r.end(); ++i)
                                      keys_[i - begin] = key(xyz_[i], voxel);
                              });
            for (std::size_t j = 0; j < end - begin; ++j) {
                const std::uint64_t key = keys_[j];
                if (key == previous) continue;
                previous = key;
                // Fibonacci hashing of the key into the table's slots, then linear probing.
                std::size_t slot =
                    static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & mask;
                while (set_[slot] != 0 && set_[slot] != key + 1) slot = (slot + 1) & mask;
                if (set_[slot] == 0) {
                    set_[slot] = key + 1;
                    if (++distinct > limit) return distinct;
                }
            }
        }
        return distinct;
    }

private:
    static constexpr std::size_t kChunk = 65536;

    std::uint64_t key(const Eigen::Vector3d& p, double voxel) const {
        const Eigen::Vector3d c = ((p - lo_) / voxel).array().floor();
        return (static_cast<std::uint64_t>(c.x()) & 0x1FFFFF) |
               ((static_cast<std::uint64_t>(c.y()) & 0x1FFFFF) << 21) |
               ((static_cast<std::uint64_t>(c.z()) & 0x1FFFFF) << 42);
    }

    const std::vector<Eigen::Vector3d>& xyz_;
    Eigen::Vector3d lo_;
    std::vector<std::uint64_t> keys_, set_;
};

}  // namespace

PointCloud bounded(const PointCloud& cloud, std::size_t max_points, double spacing, double& voxel) {
    voxel = 0.0;
    if (max_points == 0 || cloud.size() <= max_points) return cloud;
    std::vector<Eigen::Vector3d> xyz(cloud.size());
    const auto indices = cloud.points.begin();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, xyz.size(), 16384),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i)
                              xyz[i] = to_eigen(cloud.points.point(indices[i]));
                      });
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    for (const auto& p : xyz) lo = lo.cwiseMin(p);
    // The voxels tried: from ŝ sqrt(n / max), each 10% larger than the last.
    constexpr int kAttempts = 60;
    std::vector<double> voxels(kAttempts);
    voxels[0] = spacing * std::sqrt(static_cast<double>(cloud.size()) / max_points);
    for (int k = 1; k < kAttempts; ++k) voxels[k] = voxels[k - 1] * 1.1;
    VoxelCounter counter(xyz, lo);
    const auto too_many = [&](int k) { return counter.count(voxels[k], max_points) > max_points; };
    // The first voxel whose grid fits is the answer. One count at the first voxel (capped at
    // 8 budgets) predicts the attempt: a surface's voxel count falls as 1 / voxel^2, 1.21 per
    // step. The search starts one step before the prediction and goes back while that fits
    // (a count that falls faster), so the answer is the first that fits after one that does
    // not, as when every attempt is tried in turn.
    int first = 0;
    const std::size_t cap = 8 * max_points;
    const std::size_t count0 = counter.count(voxels[0], cap);
    if (count0 > max_points && count0 <= cap) {
        const double steps = std::log(static_cast<double>(count0) / max_points) / std::log(1.21);
        first = std::clamp(static_cast<int>(std::ceil(steps)) - 1, 1, kAttempts - 1);
        while (first > 1 && !too_many(first - 1)) --first;
    }
    for (int k = first; k < kAttempts; ++k) {
        if (k == 0 ? count0 > max_points : too_many(k)) continue;
        voxel = voxels[k];
        PointCloud down = sampling::voxel_downsample(cloud, voxel);
        if (down.size() <= max_points) return down;
    }
    voxel = 0.0;
    throw AlgorithmError("reconstruction: view " + std::to_string(cloud.view.id) +
                         ": cannot down-sample to the point budget");
}

}  // namespace rgbd::reconstruction::internal
