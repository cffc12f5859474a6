#include "algorithms/sampling/robust_spacing.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/spacing_sample.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::internal {

std::vector<std::uint32_t> spacing_sample(std::size_t n, std::size_t sample, std::uint64_t seed) {
    // Sample without replacement: partial Fisher-Yates with a fixed-seed generator.
    std::vector<std::uint32_t> queries(n);
    std::iota(queries.begin(), queries.end(), 0u);
    const std::size_t m = std::min(sample, n);
    if (m < n) {
        std::mt19937_64 rng(seed);
        for (std::size_t i = 0; i < m; ++i) {
            const std::size_t j = i + static_cast<std::size_t>(rng() % (n - i));
            std::swap(queries[i], queries[j]);
        }
        queries.resize(m);
    }
    return queries;
}

double spacing_median(std::vector<double>& dist) {
    const std::size_t m = dist.size();
    if (m == 0) return 0.0;
    auto mid = dist.begin() + static_cast<std::ptrdiff_t>(m / 2);
    std::nth_element(dist.begin(), mid, dist.end());
    if (m % 2 == 1) return *mid;
    const double upper = *mid;
    const double lower = *std::max_element(dist.begin(), mid);
    return 0.5 * (lower + upper);
}

}  // namespace rgbd::internal

namespace rgbd::sampling {

using internal::spacing_median;
using internal::spacing_sample;

double robust_spacing(const PointSet& points, std::size_t sample, std::uint64_t seed) {
    RGBD_CHECK(points.size() >= 2,
               "robust_spacing: needs at least 2 points, got " + std::to_string(points.size()));
    std::vector<Eigen::Vector3d> xyz;
    xyz.reserve(points.size());
    for (auto idx : points) xyz.push_back(to_eigen(points.point(idx)));
    return robust_spacing(xyz, sample, seed);
}

namespace {

/// Nearest other point's distance of every query point into `dist`, by any search with
/// knn(q, k, indices, sq_dists) over all the points (the query itself is among them: its nearest
/// other point is the first of its two nearest that is not itself, or a duplicate at 0); `cap`
/// for a query the search leaves unsettled (knn() = 0). Returns the number of those.
template <typename Search>
std::size_t nearest_other(const Search& search, const std::vector<Eigen::Vector3d>& pts,
                          const std::vector<std::uint32_t>& queries, double cap,
                          std::vector<double>& dist) {
    dist.assign(queries.size(), 0.0);
    std::atomic<std::size_t> capped{0};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::uint32_t idx[2];
                          double sq[2];
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const std::size_t found = search.knn(pts[queries[i]], 2, idx, sq);
                              if (found == 0) {
                                  dist[i] = cap;
                                  ++capped;
                              } else if (found == 2) {
                                  dist[i] = std::sqrt(idx[0] == queries[i] ? sq[1] : sq[0]);
                              }
                          }
                      });
    return capped.load();
}

/// The distances for the median from a cell grid (no kd-tree: over millions of points its
/// build is a long sequential step), cells of about the spacing a surface over the bounding
/// box's largest face would have (internal::CellNeighbours). The median only needs the exact
/// distances of the lower half: a query not settled within 2 rings of cells (an isolated
/// outlier) is farther than 2 cells from every other point and gets that lower bound, unless
/// that caps at least half the queries (then every ring is searched). False when the grid
/// cannot hold the extent.
bool grid_nearest_for_median(const std::vector<Eigen::Vector3d>& pts,
                             const std::vector<std::uint32_t>& queries, std::vector<double>& dist) {
    constexpr std::int64_t kCapRings = 2;
    internal::CellNeighbours near(pts, 1.0, kCapRings, false);  // few queries: no copy
    if (!near.ok()) return false;
    const std::size_t capped =
        nearest_other(near, pts, queries, double(kCapRings) * near.cell(), dist);
    if (capped > 0 && capped + dist.size() / 2 + 1 > dist.size()) {
        near.set_max_rings(std::numeric_limits<std::int64_t>::max());
        nearest_other(near, pts, queries, 0.0, dist);
    }
    return true;
}

}  // namespace

double robust_spacing(const std::vector<Eigen::Vector3d>& xyz, std::size_t sample,
                      std::uint64_t seed) {
    const std::size_t n = xyz.size();
    RGBD_CHECK(n >= 2, "robust_spacing: needs at least 2 points, got " + std::to_string(n));
    RGBD_CHECK(sample >= 1, "robust_spacing: sample size must be positive");
    for (std::size_t i = 0; i < n; ++i)
        RGBD_CHECK(xyz[i].allFinite(),
                   "robust_spacing: point " + std::to_string(i) + " has a non-finite coordinate");
    const std::vector<std::uint32_t> queries = spacing_sample(n, sample, seed);
    std::vector<double> dist;
    if (!grid_nearest_for_median(xyz, queries, dist))
        nearest_other(internal::KdTree(xyz), xyz, queries, 0.0, dist);
    return spacing_median(dist);
}

double median_view_spacing(const std::vector<const PointCloud*>& views, std::size_t sample) {
    std::vector<double> s;
    for (const PointCloud* v : views)
        if (v->size() >= 2) s.push_back(robust_spacing(v->points, sample));
    if (s.empty()) return 0.0;
    return upper_median(s);
}

}  // namespace rgbd::sampling
