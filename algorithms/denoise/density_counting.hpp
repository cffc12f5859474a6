// The density filter's neighbour counts (docs/algorithms.md §7, measured density): the points
// within a radius of every point, with the sums of their offsets and outer products for the PCA
// normal, on a cell grid of the radius (vectorised with SSE2 / AVX2) or a kd-tree. Internal to
// algorithms/denoise (not installed): density_outliers.cpp is its user.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#endif

#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"

namespace rgbd::denoise::detail {

/// The number of the m points (xs[j], ys[j], zs[j]) within sqrt(r2) of (px, py, pz): the
/// test dx * dx + dy * dy + dz * dz <= r2, two points at a time with SSE2 (the same IEEE
/// operations in the same order as the scalar test, so the same answer; the compiler does not
/// vectorise the scalar loop).
inline std::size_t count_within_sse2(const double* xs, const double* ys, const double* zs,
                                     std::size_t m, double px, double py, double pz, double r2) {
    std::size_t j = 0, count = 0;
#if defined(__SSE2__)
    const __m128d vx = _mm_set1_pd(px), vy = _mm_set1_pd(py), vz = _mm_set1_pd(pz),
                  vr = _mm_set1_pd(r2);
    __m128i lanes = _mm_setzero_si128();  // minus the number of hits in each lane
    for (; j + 2 <= m; j += 2) {
        const __m128d dx = _mm_sub_pd(_mm_loadu_pd(xs + j), vx);
        const __m128d dy = _mm_sub_pd(_mm_loadu_pd(ys + j), vy);
        const __m128d dz = _mm_sub_pd(_mm_loadu_pd(zs + j), vz);
        const __m128d d2 =
            _mm_add_pd(_mm_add_pd(_mm_mul_pd(dx, dx), _mm_mul_pd(dy, dy)), _mm_mul_pd(dz, dz));
        lanes = _mm_add_epi64(lanes, _mm_castpd_si128(_mm_cmple_pd(d2, vr)));
    }
    alignas(16) std::int64_t sums[2];
    _mm_store_si128(reinterpret_cast<__m128i*>(sums), lanes);
    count = std::size_t(-(sums[0] + sums[1]));
#endif
    for (; j < m; ++j) {
        const double dx = xs[j] - px, dy = ys[j] - py, dz = zs[j] - pz;
        count += dx * dx + dy * dy + dz * dz <= r2;
    }
    return count;
}

#if defined(__GNUC__) && defined(__x86_64__)
#define RGBD_DENSITY_AVX2 1
/// count_within_sse2() four points at a time with AVX2 (not FMA: separate multiplies and adds,
/// so the same answers), for CPUs that have it.
__attribute__((target("avx2"))) inline std::size_t count_within_avx2(
    const double* xs, const double* ys, const double* zs, std::size_t m, double px, double py,
    double pz, double r2) {
    std::size_t j = 0;
    const __m256d vx = _mm256_set1_pd(px), vy = _mm256_set1_pd(py), vz = _mm256_set1_pd(pz),
                  vr = _mm256_set1_pd(r2);
    __m256i lanes = _mm256_setzero_si256();  // minus the number of hits in each lane
    for (; j + 4 <= m; j += 4) {
        const __m256d dx = _mm256_sub_pd(_mm256_loadu_pd(xs + j), vx);
        const __m256d dy = _mm256_sub_pd(_mm256_loadu_pd(ys + j), vy);
        const __m256d dz = _mm256_sub_pd(_mm256_loadu_pd(zs + j), vz);
        const __m256d d2 = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
        lanes = _mm256_add_epi64(lanes, _mm256_castpd_si256(_mm256_cmp_pd(d2, vr, _CMP_LE_OQ)));
    }
    alignas(32) std::int64_t sums[4];
    _mm256_store_si256(reinterpret_cast<__m256i*>(sums), lanes);
    return std::size_t(-(sums[0] + sums[1] + sums[2] + sums[3])) +
           count_within_sse2(xs + j, ys + j, zs + j, m - j, px, py, pz, r2);
}
#endif

/// count_within_sse2() with AVX2 when the CPU has it.
inline std::size_t count_within(const double* xs, const double* ys, const double* zs, std::size_t m,
                                double px, double py, double pz, double r2) {
#if defined(RGBD_DENSITY_AVX2)
    static const bool avx2 = __builtin_cpu_supports("avx2");
    if (avx2) return count_within_avx2(xs, ys, zs, m, px, py, pz, r2);
#endif
    return count_within_sse2(xs, ys, zs, m, px, py, pz, r2);
}

/// Calls finish(i, count, sum, outer) for every point i of `world` with the number of points
/// within sqrt(r2) of it (itself included) and, unless `count_only`, the sum and the sum of
/// outer products of their offsets; counted cell by cell on `grid` (side sqrt(r2)): 27 cells
/// per point, no tree.
template <class Finish>
void count_on_grid(const internal::CellGrid& grid, const std::vector<Eigen::Vector3d>& world,
                   double r2, bool count_only, const Finish& finish) {
    const std::size_t n = world.size();
    // Coordinates in cell order, one array per axis: a cell column (cx, cy, z - 1 .. z + 1) is
    // one contiguous run, so 9 runs cover the 27 cells around a point.
    std::vector<double> xs(n), ys(n), zs(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t a = r.begin(); a != r.end(); ++a) {
                              const Eigen::Vector3d& p = world[grid.point[a]];
                              xs[a] = p.x();
                              ys[a] = p.y();
                              zs[a] = p.z();
                          }
                      });
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, grid.cells(), 64),
        [&](const tbb::blocked_range<std::size_t>& r) {
            std::pair<std::uint32_t, std::uint32_t> runs[9];
            for (std::size_t ca = r.begin(); ca != r.end(); ++ca) {
                const std::uint64_t key = grid.keys[ca];
                const std::uint64_t x = key >> 42, y = (key >> 21) & internal::kKeyMask,
                                    z = key & internal::kKeyMask;
                int nr = 0;
                for (std::int64_t cx = std::int64_t(x) - 1; cx <= std::int64_t(x) + 1; ++cx)
                    for (std::int64_t cy = std::int64_t(y) - 1; cy <= std::int64_t(y) + 1; ++cy) {
                        const auto [c0, c1] =
                            grid.column(cx, cy, std::int64_t(z) - 1, std::int64_t(z) + 1);
                        if (c0 == c1) continue;
                        runs[nr++] = {grid.start[c0], grid.start[c1]};
                    }
                for (std::uint32_t a = grid.start[ca]; a < grid.start[ca + 1]; ++a) {
                    const double px = xs[a], py = ys[a], pz = zs[a];
                    std::size_t count = 0;
                    if (count_only) {
                        for (int q = 0; q < nr; ++q)
                            count +=
                                count_within(xs.data() + runs[q].first, ys.data() + runs[q].first,
                                             zs.data() + runs[q].first,
                                             runs[q].second - runs[q].first, px, py, pz, r2);
                        finish(grid.point[a], count, Eigen::Vector3d::Zero(),
                               Eigen::Matrix3d::Zero());
                        continue;
                    }
                    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                    Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
                    for (int q = 0; q < nr; ++q)
                        for (std::uint32_t b = runs[q].first; b < runs[q].second; ++b) {
                            const Eigen::Vector3d d(xs[b] - px, ys[b] - py, zs[b] - pz);
                            if (d.squaredNorm() > r2) continue;
                            ++count;
                            sum += d;
                            outer += d * d.transpose();
                        }
                    finish(grid.point[a], count, sum, outer);
                }
            }
        });
}

/// The same neighbourhoods as count_on_grid() from a kd-tree, for an extent too large for the
/// grid (always with the moments).
template <class Finish>
void count_with_tree(const std::vector<Eigen::Vector3d>& world, double radius,
                     const Finish& finish) {
    const internal::KdTree tree(world);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, world.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::vector<std::pair<std::uint32_t, double>> found;
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              tree.radius(world[i], radius, found, /*sorted=*/false);
                              Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                              Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
                              for (const auto& f : found) {
                                  const Eigen::Vector3d d = world[f.first] - world[i];
                                  sum += d;
                                  outer += d * d.transpose();
                              }
                              finish(i, found.size(), sum, outer);
                          }
                      });
}

}  // namespace rgbd::denoise::detail
