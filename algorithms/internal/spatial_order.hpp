// Morton (Z-curve) order of query points, so that neighbouring queries run one after the other:
// they walk the same parts of a search structure, and one's answer bounds the next one's
// (CellNeighbours::knn's bound). Internal to algorithms/: not a public header.
#pragma once

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Core>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

namespace rgbd::internal {

/// The indices of `points` in Morton order of a 1024^3 grid over their bounding box (ties by
/// index): neighbouring queries run one after the other and walk the same parts of a search
/// structure, where the callers' random order (area-uniform samples) missed the cache.
inline std::vector<std::uint32_t> spatial_order(const std::vector<Eigen::Vector3d>& points) {
    std::vector<std::uint32_t> order(points.size());
    std::iota(order.begin(), order.end(), 0u);
    if (points.size() < 2) return order;
    Eigen::Vector3d lo = points[0], hi = points[0];
    for (const auto& p : points) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const double extent = (hi - lo).maxCoeff();
    if (!(extent > 0.0)) return order;
    const auto spread = [](std::uint64_t v) {  // 10 bits -> every third bit
        v &= 0x3FF;
        v = (v | (v << 16)) & 0x30000FF;
        v = (v | (v << 8)) & 0x300F00F;
        v = (v | (v << 4)) & 0x30C30C3;
        v = (v | (v << 2)) & 0x9249249;
        return v;
    };
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(points.size());
    tbb::parallel_for(std::size_t(0), points.size(), [&](std::size_t i) {
        const Eigen::Vector3d c = ((points[i] - lo) / extent * 1023.0).cwiseMax(0.0);
        keyed[i] = {spread(std::uint64_t(c.x())) | (spread(std::uint64_t(c.y())) << 1) |
                        (spread(std::uint64_t(c.z())) << 2),
                    static_cast<std::uint32_t>(i)};
    });
    tbb::parallel_sort(keyed.begin(), keyed.end());
    for (std::size_t i = 0; i < keyed.size(); ++i) order[i] = keyed[i].second;
    return order;
}

}  // namespace rgbd::internal
