#include "algorithms/denoise/density_clusters.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>
#include <utility>

#include "algorithms/denoise/eps_components.hpp"
#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/kd_tree.hpp"

namespace rgbd::denoise::detail {

namespace {

/// Component label of every point of `pts` in the graph linking points within eps (equal labels
/// = one component): exact eps-graph components on a cell grid, or, when the grid is too fine
/// for the extent, from a radius search per point.
std::vector<std::uint32_t> eps_labels(const std::vector<Eigen::Vector3d>& pts, double eps) {
    std::vector<std::uint32_t> label;
    if (eps_components(pts, eps, label)) return label;
    const std::size_t m = pts.size();
    const internal::KdTree alive_tree(pts);
    constexpr std::size_t kBlock = 1024;
    const std::size_t blocks = (m + kBlock - 1) / kBlock;
    std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> edges(blocks);
    tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
        std::vector<std::pair<std::uint32_t, double>> found;
        for (std::size_t a = b * kBlock; a < std::min(m, (b + 1) * kBlock); ++a) {
            alive_tree.radius(pts[a], eps, found, /*sorted=*/false);
            for (const auto& f : found)
                if (f.first > a) edges[b].emplace_back(std::uint32_t(a), f.first);
        }
    });
    DisjointSets sets(m);
    for (const auto& block : edges)
        for (const auto& e : block) sets.unite(e.first, e.second);
    label.resize(m);
    for (std::size_t a = 0; a < m; ++a) label[a] = sets.find(std::uint32_t(a));
    return label;
}

}  // namespace

/// The cluster pass over the survivors (density_clusters.hpp).
ClusterCount flag_small_clusters(const std::vector<Eigen::Vector3d>& world, double eps,
                                 double min_cluster_fraction, std::vector<std::uint8_t>& outlier,
                                 Report& report, const std::vector<std::uint8_t>* only) {
    ClusterCount result;
    std::vector<std::uint32_t> alive;
    for (std::size_t i = 0; i < world.size(); ++i)
        if (!outlier[i] && (!only || (*only)[i])) alive.push_back(static_cast<std::uint32_t>(i));
    const std::size_t m = alive.size();
    if (m < 2) return result;
    std::vector<Eigen::Vector3d> pts(m);
    for (std::size_t a = 0; a < m; ++a) pts[a] = world[alive[a]];
    report["cluster_eps_m"] = eps;
    const std::vector<std::uint32_t> label = eps_labels(pts, eps);
    // Per component: size and first member (the tie-break of the largest).
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> size(m, 0), first(m, kNone);
    for (std::size_t a = 0; a < m; ++a) {
        ++size[label[a]];
        if (first[label[a]] == kNone) first[label[a]] = std::uint32_t(a);
    }
    std::uint32_t largest = label[0];
    for (std::size_t c = 0; c < m; ++c) {
        if (size[c] == 0) continue;
        ++result.clusters;
        if (size[c] > size[largest] || (size[c] == size[largest] && first[c] < first[largest]))
            largest = std::uint32_t(c);
    }
    const double keep = min_cluster_fraction * double(m);
    for (std::size_t a = 0; a < m; ++a) {
        const std::uint32_t root = label[a];
        if (root != largest && double(size[root]) < keep) {
            outlier[alive[a]] = 1;
            ++result.removed;
        }
    }
    return result;
}

}  // namespace rgbd::denoise::detail
