#include "algorithms/sampling/robust_spacing.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

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

double robust_spacing(const std::vector<Eigen::Vector3d>& xyz, std::size_t sample,
                      std::uint64_t seed) {
    const std::size_t n = xyz.size();
    RGBD_CHECK(n >= 2, "robust_spacing: needs at least 2 points, got " + std::to_string(n));
    RGBD_CHECK(sample >= 1, "robust_spacing: sample size must be positive");
    for (std::size_t i = 0; i < n; ++i)
        RGBD_CHECK(xyz[i].allFinite(),
                   "robust_spacing: point " + std::to_string(i) + " has a non-finite coordinate");

    const std::vector<std::uint32_t> queries = spacing_sample(n, sample, seed);
    const std::size_t m = queries.size();

    const internal::KdTree tree(xyz);
    std::vector<double> dist(m, 0.0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m, 512),
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
