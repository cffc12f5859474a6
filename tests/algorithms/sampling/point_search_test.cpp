// internal::PointSearch / CellNeighbours (algorithms/internal/cell_grid.hpp): exact k nearest
// neighbours on cell grids must equal a kd-tree's, near the points, far from them, outside the
// grid, with duplicates and on clouds no grid can hold; robust_spacing (which now searches a
// cell grid) must equal a brute-force median.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/spatial_order.hpp"
#include "algorithms/sampling/robust_spacing.hpp"

namespace {

using rgbd::internal::KdTree;
using rgbd::internal::PointSearch;

/// A surface-like cloud: a noisy sphere of radius 0.3 m and a plane patch below it, with a
/// cluster of exact duplicates and a few isolated outliers.
std::vector<Eigen::Vector3d> scene(std::size_t n, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<Eigen::Vector3d> pts;
    for (std::size_t i = 0; i < n; ++i) {
        if (i % 3 == 0) {
            pts.emplace_back(0.6 * u(rng), 0.6 * u(rng), -0.35 + 0.0005 * g(rng));
        } else {
            const Eigen::Vector3d d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
            pts.push_back((0.3 + 0.0005 * g(rng)) * d);
        }
    }
    for (int i = 0; i < 40; ++i) pts.push_back(pts[7]);  // duplicates
    for (int i = 0; i < 20; ++i) pts.emplace_back(2.0 * u(rng), 2.0 * u(rng), 1.0 + u(rng));
    return pts;
}

/// Queries on the points, just off them, inside the sphere, far away and far outside the grid.
std::vector<Eigen::Vector3d> queries(const std::vector<Eigen::Vector3d>& pts, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<Eigen::Vector3d> q;
    for (std::size_t i = 0; i < pts.size(); i += 97) q.push_back(pts[i]);
    for (std::size_t i = 0; i < pts.size(); i += 89)
        q.push_back(pts[i] + 0.004 * Eigen::Vector3d(u(rng), u(rng), u(rng)));
    for (int i = 0; i < 200; ++i) q.push_back(0.1 * Eigen::Vector3d(u(rng), u(rng), u(rng)));
    for (int i = 0; i < 50; ++i) q.push_back(5.0 * Eigen::Vector3d(u(rng), u(rng), u(rng)));
    q.emplace_back(1e9, -1e9, 3.0);
    if (pts.size() > 7) q.push_back(pts[7]);
    return q;
}

/// The k nearest of a PointSearch equal a kd-tree's: the same squared distances in the same
/// order, and the same points wherever a distance is not tied with another.
void expect_same_as_kd_tree(const std::vector<Eigen::Vector3d>& pts, std::size_t k) {
    const PointSearch search(pts);
    const KdTree tree(pts);
    const auto q = queries(pts, 11);
    // The kd-tree's (k + 1)-th neighbour tells whether the k-th is tied with a point left out.
    std::vector<std::uint32_t> a(k), b(k + 1);
    std::vector<double> da(k), db(k + 1);
    for (std::size_t i = 0; i < q.size(); ++i) {
        const std::size_t fa = search.knn(q[i], k, a.data(), da.data());
        const std::size_t fb = tree.knn(q[i], k + 1, b.data(), db.data());
        ASSERT_EQ(fa, std::min(fb, k)) << "query " << i;
        for (std::size_t j = 0; j < fa; ++j) {
            ASSERT_EQ(da[j], db[j]) << "query " << i << " neighbour " << j;
            const bool tied = (j > 0 && db[j - 1] == db[j]) || (j + 1 < fb && db[j + 1] == db[j]);
            if (!tied) {
                EXPECT_EQ(a[j], b[j]) << "query " << i << " neighbour " << j;
            }
        }
    }
}

TEST(PointSearch, EqualsAKdTreeNearAndFarFromTheSurface) {
    // 200001 points: the grid is sorted and indexed in three uneven chunks.
    const auto pts = scene(200001, 1);
    for (std::size_t k : {1u, 8u, 24u}) expect_same_as_kd_tree(pts, k);
}

TEST(PointSearch, TiesAreOrderedByPointIndex) {
    const auto pts = scene(5000, 2);
    const PointSearch search(pts);
    std::uint32_t idx[45];
    double sq[45];
    ASSERT_EQ(search.knn(pts[7], 45, idx, sq), 45u);
    // Point 7 and its 40 copies (indices 5000 ..) are at distance 0, in index order.
    for (int j = 0; j < 41; ++j) EXPECT_EQ(sq[j], 0.0);
    for (int j = 1; j < 41; ++j) EXPECT_LT(idx[j - 1], idx[j]);
    EXPECT_EQ(idx[0], 7u);
}

TEST(PointSearch, ABoundFromAnotherQueryGivesTheSameNeighbours) {
    // The bound a caller passes: the largest distance from q to the previous (nearby) query's
    // k neighbours, which any k points give; exact bounds (the k-th distance itself, ties
    // included), loose ones and ones too small (then dropped) leave the answer unchanged.
    const auto pts = scene(60000, 4);
    const PointSearch search(pts);
    std::vector<Eigen::Vector3d> q;  // in space order, as the callers ask them
    const auto unordered = queries(pts, 12);
    for (const std::uint32_t i : rgbd::internal::spatial_order(unordered))
        q.push_back(unordered[i]);
    for (const std::size_t k : {1u, 8u}) {
        std::vector<std::uint32_t> a(k), b(k), last(k);
        std::vector<double> da(k), db(k);
        bool have = false;
        for (std::size_t i = 0; i < q.size(); ++i) {
            const std::size_t fa = search.knn(q[i], k, a.data(), da.data());
            ASSERT_GT(fa, 0u);
            const double kth = da[fa - 1];
            double from_last = std::numeric_limits<double>::infinity();
            if (have) {
                from_last = 0.0;
                for (const std::uint32_t j : last)
                    from_last = std::max(from_last, (pts[j] - q[i]).squaredNorm());
            }
            for (const double bound : {from_last, kth, 4.0 * kth + 1e-6, 0.25 * kth}) {
                const std::size_t fb = search.knn(q[i], k, b.data(), db.data(), bound);
                ASSERT_EQ(fa, fb) << "query " << i << " bound " << bound;
                for (std::size_t j = 0; j < fa; ++j) {
                    ASSERT_EQ(da[j], db[j]) << "query " << i << " neighbour " << j << " bound "
                                            << bound << " k-th " << kth;
                    ASSERT_EQ(a[j], b[j]) << "query " << i << " neighbour " << j;
                }
            }
            have = fa == k;
            std::copy(a.begin(), a.begin() + fa, last.begin());
        }
    }
}

// The grid's radix sort (chunks counted and scattered in parallel) is the stable sort by value,
// on sizes that give one chunk, several and an uneven last one, with many equal values, and on
// one thread as on all.
TEST(PointSearch, CellGridRadixSortIsTheStableSortByValue) {
    using Pair = std::pair<std::uint32_t, std::uint32_t>;
    std::mt19937_64 rng(11);
    for (const std::size_t n :
         {std::size_t(0), std::size_t(1000), std::size_t(200000), std::size_t(1234567)}) {
        std::vector<Pair> a(n);
        for (std::size_t i = 0; i < n; ++i)
            a[i] = {std::uint32_t(rng() % (i % 3 == 0 ? 50u : 4000000000u)), std::uint32_t(i)};
        std::vector<Pair> expected = a;
        std::stable_sort(expected.begin(), expected.end(),
                         [](const Pair& x, const Pair& y) { return x.first < y.first; });
        std::vector<Pair> sorted = a, scratch(n);
        rgbd::internal::CellGrid::radix_sort(sorted, scratch);
        EXPECT_TRUE(sorted == expected) << n << " pairs";
        std::vector<Pair> one = a;
        {
            tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
            rgbd::internal::CellGrid::radix_sort(one, scratch);
        }
        EXPECT_TRUE(one == expected) << n << " pairs, one thread";
    }
}

TEST(PointSearch, FewerPointsThanAskedAndCloudsNoGridHolds) {
    const std::vector<Eigen::Vector3d> few{{0, 0, 0}, {0.01, 0, 0}, {0, 0.02, 0}};
    expect_same_as_kd_tree(few, 8);
    // All points equal: no cell size; and an extent beyond 21 bits of cells per axis.
    expect_same_as_kd_tree(std::vector<Eigen::Vector3d>(50, Eigen::Vector3d(1, 2, 3)), 4);
    auto wide = scene(3000, 3);
    wide.emplace_back(1e7, 0.0, 0.0);
    expect_same_as_kd_tree(wide, 6);
    const std::vector<Eigen::Vector3d> empty;
    const PointSearch none(empty);
    std::uint32_t i;
    double d;
    EXPECT_EQ(none.knn(Eigen::Vector3d::Zero(), 1, &i, &d), 0u);
}

TEST(PointSearch, RobustSpacingEqualsTheBruteForceMedian) {
    const auto pts = scene(6000, 4);
    // The median of the nearest other point's distance over the sample robust_spacing draws
    // (all points: n <= sample), by brute force.
    std::vector<double> d(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t j = 0; j < pts.size(); ++j)
            if (j != i) best = std::min(best, (pts[j] - pts[i]).squaredNorm());
        d[i] = std::sqrt(best);
    }
    std::sort(d.begin(), d.end());
    const double median =
        d.size() % 2 ? d[d.size() / 2] : 0.5 * (d[d.size() / 2 - 1] + d[d.size() / 2]);
    EXPECT_EQ(rgbd::sampling::robust_spacing(pts, 10000, 0), median);
}

}  // namespace
