#include "algorithms/sampling/robust_spacing.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
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

/// Nearest other point's distance of every query point, from a kd-tree over all points.
std::vector<double> kd_nearest(const std::vector<Eigen::Vector3d>& xyz,
                               const std::vector<std::uint32_t>& queries) {
    const internal::KdTree tree(xyz);
    std::vector<double> dist(queries.size(), 0.0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, queries.size(), 512),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          std::uint32_t idx[2];
                          double sq[2];
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const std::size_t found = tree.knn(xyz[queries[i]], 2, idx, sq);
                              // The query itself is in the tree; its nearest "other" point is
                              // the second result (or the first, if a duplicate came first).
                              double d2 = 0.0;
                              if (found == 2) d2 = idx[0] == queries[i] ? sq[1] : sq[0];
                              dist[i] = std::sqrt(d2);
                          }
                      });
    return dist;
}

/// The same distances for the median, from a cell grid (no kd-tree: over millions of points
/// its build is a long sequential step): cells of side c ~ the spacing a surface over the
/// bounding box's largest face would have; rings of cells around the query's are searched
/// until the best distance is at most R c after ring R (any point outside ring R is farther
/// than R c). The median only needs the exact distances of the lower half: a query not settled
/// within 2 rings (an isolated outlier) gets the lower bound 2 c, unless that caps at least
/// half the queries (then every ring is searched). False when the grid cannot hold the extent.
bool grid_nearest_for_median(const std::vector<Eigen::Vector3d>& pts,
                             const std::vector<std::uint32_t>& queries, std::vector<double>& dist) {
    const std::size_t n = pts.size();
    Eigen::Vector3d lo = pts[0], hi = pts[0];
    for (const auto& p : pts) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    Eigen::Vector3d ext = hi - lo;
    std::sort(ext.data(), ext.data() + 3);
    const double cell = std::sqrt(ext[2] * std::max(ext[1], 1e-3 * ext[2]) / double(n));
    internal::CellGrid grid;
    if (!(cell > 0.0) || !grid.build(pts, cell)) return false;
    // Rings beyond the grid's extent hold no cells: the search is complete there.
    const Eigen::Vector3d span = (hi - lo) / cell;
    const std::int64_t all_rings = std::int64_t(span.maxCoeff()) + 2;
    constexpr std::int64_t kCapRings = 2;
    std::int64_t max_ring = std::min(all_rings, kCapRings);
    dist.assign(queries.size(), 0.0);
    const auto search = [&] {
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, queries.size(), 256),
            [&](const tbb::blocked_range<std::size_t>& r) {
                for (std::size_t i = r.begin(); i != r.end(); ++i) {
                    const std::uint32_t qi = queries[i];
                    const Eigen::Vector3d& p = pts[qi];
                    const auto c = grid.cell_of(p);
                    double best = std::numeric_limits<double>::infinity();
                    // Cells (x, y, z0 .. z1) of one column.
                    const auto visit = [&](std::int64_t x, std::int64_t y, std::int64_t z0,
                                           std::int64_t z1) {
                        const auto [c0, c1] = grid.column(x, y, z0, z1);
                        for (std::uint32_t a = grid.start[c0]; a < grid.start[c1]; ++a) {
                            const std::uint32_t j = grid.keyed[a].second;
                            if (j != qi) best = std::min(best, (pts[j] - p).squaredNorm());
                        }
                    };
                    visit(c.x(), c.y(), c.z(), c.z());
                    for (std::int64_t ring = 1; ring <= max_ring; ++ring) {
                        // The shell at Chebyshev distance `ring`: full columns on its x / y
                        // faces, the two z caps elsewhere.
                        for (std::int64_t x = c.x() - ring; x <= c.x() + ring; ++x)
                            for (std::int64_t y = c.y() - ring; y <= c.y() + ring; ++y) {
                                if (std::abs(x - c.x()) == ring || std::abs(y - c.y()) == ring) {
                                    visit(x, y, c.z() - ring, c.z() + ring);
                                } else {
                                    visit(x, y, c.z() - ring, c.z() - ring);
                                    visit(x, y, c.z() + ring, c.z() + ring);
                                }
                            }
                        if (best <= double(ring) * cell * double(ring) * cell) break;
                    }
                    dist[i] = std::min(std::sqrt(best), double(max_ring) * cell);
                }
            });
    };
    search();
    const std::size_t m = dist.size();
    const std::size_t capped =
        std::size_t(std::count(dist.begin(), dist.end(), double(max_ring) * cell));
    if (max_ring < all_rings && capped > 0 && capped + m / 2 + 1 > m) {
        max_ring = all_rings;
        search();
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
    if (!grid_nearest_for_median(xyz, queries, dist)) dist = kd_nearest(xyz, queries);
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
