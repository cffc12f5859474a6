// Points binned in cubic cells with 21-bit keys per axis, sorted by cell (the density filter's
// neighbour counts, the eps graph's components), and exact k-nearest-neighbour queries on it
// for dense clouds (robust spacing, colours of mesh vertices, distances to the input points):
// binning is O(n) and parallel, where building a kd-tree over millions of points is a long
// sequential step. Internal to algorithms/ (not installed).
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "algorithms/internal/kd_tree.hpp"

namespace rgbd::internal {

/// Key of cell (x, y, z), 21 bits per axis.
constexpr std::uint64_t key_of(std::uint64_t x, std::uint64_t y, std::uint64_t z) {
    return (x << 42) | (y << 21) | z;
}
constexpr std::uint64_t kKeyMask = (std::uint64_t(1) << 21) - 1;

/// Points binned in cubic cells of side `cell` (cell coordinates offset by 2, so that
/// neighbour offsets -2..2 never underflow), sorted by cell key.
struct CellGrid {
    std::vector<std::uint32_t> point;  ///< the points in cell order (by point within a cell)
    std::vector<std::uint64_t> keys;   ///< unique cell keys, sorted
    std::vector<std::uint32_t> start;  ///< cell c's points: point[start[c], start[c + 1])

    /// False (grid left empty) when the extent needs more than 21 bits per axis.
    bool build(const std::vector<Eigen::Vector3d>& pts, double cell) {
        if (pts.empty()) return false;
        const auto [lo, hi] = bounds(pts);
        return build(pts, cell, lo, hi);
    }
    /// The same with the points' bounding box `lo`, `hi` already known.
    bool build(const std::vector<Eigen::Vector3d>& pts, double cell, const Eigen::Vector3d& lo,
               const Eigen::Vector3d& hi) {
        const std::size_t m = pts.size();
        if (!(cell > 0.0) || m == 0) return false;
        constexpr double kMaxCells = double(1 << 21) - 8.0;
        if (((hi - lo) / cell).maxCoeff() >= kMaxCells) return false;
        origin = lo;
        side = cell;
        const Eigen::Vector3d span = (hi - lo) / cell;
        const auto coords = [&](std::size_t a) {
            const Eigen::Vector3d c = (pts[a] - lo) / cell;
            return Eigen::Matrix<std::uint64_t, 3, 1>(
                std::uint64_t(c.x()) + 2, std::uint64_t(c.y()) + 2, std::uint64_t(c.z()) + 2);
        };
        // Cells (x, y, z) in key order, points in increasing order within a cell.
        const double lx = std::floor(span.x()) + 5, ly = std::floor(span.y()) + 5,
                     lz = std::floor(span.z()) + 5;
        point.resize(m);
        if (lx * ly * lz < 4294967295.0) {
            // A stable LSD radix sort of the linear cell index (x ly + y) lz + z, which orders
            // cells as the keys do (3 passes of 11 bits); 16 bytes a point while it runs.
            const std::uint64_t my = std::uint64_t(ly), mz = std::uint64_t(lz);
            std::vector<std::pair<std::uint32_t, std::uint32_t>> a(m), b(m);
            tbb::parallel_for(
                tbb::blocked_range<std::size_t>(0, m, 4096),
                [&](const tbb::blocked_range<std::size_t>& r) {
                    for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        const auto c = coords(i);
                        a[i] = {std::uint32_t((c.x() * my + c.y()) * mz + c.z()), std::uint32_t(i)};
                    }
                });
            radix_sort(a, b);
            // The points in cell order, and each cell's key and first point: fixed chunks
            // count their cells, then write them at their offsets, in parallel.
            const std::size_t chunks = fixed_chunks(m);
            const auto chunk_begin = [&](std::size_t c) { return chunk_start(m, chunks, c); };
            const auto first_of_cell = [&](std::size_t i) {
                return i == 0 || a[i].first != a[i - 1].first;
            };
            std::vector<std::size_t> cells_before(chunks + 1, 0);
            tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
                std::size_t count = 0;
                for (std::size_t i = chunk_begin(c); i < chunk_begin(c + 1); ++i) {
                    point[i] = a[i].second;
                    count += first_of_cell(i);
                }
                cells_before[c + 1] = count;
            });
            for (std::size_t c = 0; c < chunks; ++c) cells_before[c + 1] += cells_before[c];
            const std::size_t base = keys.size();
            keys.resize(base + cells_before[chunks]);
            start.resize(base + cells_before[chunks]);
            tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
                std::size_t k = base + cells_before[c];
                for (std::size_t i = chunk_begin(c); i < chunk_begin(c + 1); ++i) {
                    if (!first_of_cell(i)) continue;
                    const std::uint64_t lin = a[i].first;
                    keys[k] = key_of(lin / (my * mz), (lin / mz) % my, lin % mz);
                    start[k++] = std::uint32_t(i);
                }
            });
        } else {
            std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(m);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m, 4096),
                              [&](const tbb::blocked_range<std::size_t>& r) {
                                  for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                      const auto c = coords(i);
                                      keyed[i] = {key_of(c.x(), c.y(), c.z()), std::uint32_t(i)};
                                  }
                              });
            tbb::parallel_sort(keyed.begin(), keyed.end());
            for (std::size_t i = 0; i < m; ++i) {
                point[i] = keyed[i].second;
                if (i == 0 || keyed[i].first != keyed[i - 1].first) {
                    keys.push_back(keyed[i].first);
                    start.push_back(std::uint32_t(i));
                }
            }
        }
        start.push_back(std::uint32_t(m));
        // Dense column index when it is small next to the points (it nearly always is for
        // surfaces): column (x, y)'s cells are keys[column_start[x ny + y], ... + 1]).
        nx = std::size_t(span.x()) + 5;
        ny = std::size_t(span.y()) + 5;
        if (nx * ny <= 4 * m + 4096) {
            column_start.assign(nx * ny + 1, 0);
            for (const std::uint64_t key : keys)
                ++column_start[std::size_t(key >> 42) * ny + std::size_t((key >> 21) & kKeyMask) +
                               1];
            for (std::size_t c = 0; c < nx * ny; ++c) column_start[c + 1] += column_start[c];
        }
        return true;
    }
    /// Bounding box (lo, hi) of a non-empty point set.
    static std::pair<Eigen::Vector3d, Eigen::Vector3d> bounds(
        const std::vector<Eigen::Vector3d>& pts) {
        Eigen::Vector3d lo = pts[0], hi = pts[0];
        for (const auto& p : pts) {
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
        return {lo, hi};
    }
    std::size_t cells() const { return keys.size(); }
    /// Corner of cell (2, 2, 2): the points' lowest coordinates (after build()).
    const Eigen::Vector3d& lowest() const { return origin; }
    /// Grid coordinates of the cell holding p (offset included), as build() assigns them.
    Eigen::Matrix<std::int64_t, 3, 1> cell_of(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d c = (p - origin) / side;
        return {std::int64_t(c.x()) + 2, std::int64_t(c.y()) + 2, std::int64_t(c.z()) + 2};
    }

    /// How many chunks build() and radix_sort() split n items into for their parallel passes:
    /// one per 65536 items, 1 to 16, from n alone (so the results do not depend on the threads).
    static std::size_t fixed_chunks(std::size_t n) {
        return std::clamp<std::size_t>(n / 65536, 1, 16);
    }
    /// Where chunk c of `chunks` nearly equal chunks of n items starts (c = chunks: n).
    static std::size_t chunk_start(std::size_t n, std::size_t chunks, std::size_t c) {
        return n / chunks * c + std::min(c, n % chunks);
    }

    /// Stable LSD radix sort of (value, point) pairs by value, 3 passes of 11 bits; `b` is
    /// scratch of the same size. Each pass counts and scatters fixed chunks of `a` in parallel:
    /// a chunk's pairs of a digit go after those of the chunks before it, so the order is the
    /// sequential sort's whatever the threads (the chunks depend on the size alone).
    static void radix_sort(std::vector<std::pair<std::uint32_t, std::uint32_t>>& a,
                           std::vector<std::pair<std::uint32_t, std::uint32_t>>& b) {
        constexpr int kBits = 11;
        constexpr std::uint32_t kBuckets = 1u << kBits;
        const std::size_t n = a.size();
        const std::size_t chunks = fixed_chunks(n);
        const auto chunk_begin = [&](std::size_t c) { return chunk_start(n, chunks, c); };
        std::vector<std::uint32_t> count(chunks * kBuckets);
        for (int shift = 0; shift < 32; shift += kBits) {
            tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
                std::uint32_t* own = count.data() + c * kBuckets;
                std::fill(own, own + kBuckets, 0u);
                for (std::size_t i = chunk_begin(c); i < chunk_begin(c + 1); ++i)
                    ++own[(a[i].first >> shift) & (kBuckets - 1)];
            });
            std::uint32_t sum = 0;
            for (std::uint32_t d = 0; d < kBuckets; ++d)
                for (std::size_t c = 0; c < chunks; ++c) {
                    std::uint32_t& slot = count[c * kBuckets + d];
                    const std::uint32_t here = slot;
                    slot = sum;
                    sum += here;
                }
            tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
                std::uint32_t* own = count.data() + c * kBuckets;
                for (std::size_t i = chunk_begin(c); i < chunk_begin(c + 1); ++i)
                    b[own[(a[i].first >> shift) & (kBuckets - 1)]++] = a[i];
            });
            a.swap(b);
        }
    }

    /// The cells (x, y, z0 .. z1) (grid coordinates, offset included) as a range [first, last)
    /// of cell indices; empty outside the grid.
    std::pair<std::size_t, std::size_t> column(std::int64_t x, std::int64_t y, std::int64_t z0,
                                               std::int64_t z1) const {
        constexpr std::int64_t kLimit = std::int64_t(1) << 21;
        if (x < 0 || y < 0 || x >= kLimit || y >= kLimit) return {0, 0};
        z0 = std::max<std::int64_t>(0, z0);
        z1 = std::min<std::int64_t>(kLimit - 1, z1);
        if (z0 > z1) return {0, 0};
        const std::uint64_t first = key_of(std::uint64_t(x), std::uint64_t(y), std::uint64_t(z0));
        const std::uint64_t last = key_of(std::uint64_t(x), std::uint64_t(y), std::uint64_t(z1));
        std::size_t b = 0, e = keys.size();
        if (!column_start.empty()) {
            if (std::size_t(x) >= nx || std::size_t(y) >= ny) return {0, 0};
            const std::size_t c = std::size_t(x) * ny + std::size_t(y);
            b = column_start[c];
            e = column_start[c + 1];
            while (b < e && keys[b] < first) ++b;  // a surface crosses a column in few cells
        } else {
            b = std::size_t(std::lower_bound(keys.begin(), keys.end(), first) - keys.begin());
        }
        std::size_t l = b;
        while (l < e && keys[l] <= last) ++l;
        return {b, l};
    }

private:
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();
    double side = 0.0;
    std::size_t nx = 0, ny = 0;
    std::vector<std::uint32_t> column_start;
};

/// Exact k nearest neighbours of query points among `pts` on a CellGrid whose cells are
/// `cell_factor` times the spacing a surface over the points' bounding box would have. Shells
/// of cells (Chebyshev rings) around the query's cell are searched until the k-th best distance
/// is at most R times the cell side after ring R: every point outside ring R is farther than
/// that. A query not settled within `max_rings` rings returns 0 (see PointSearch for a search
/// that always answers). Results equal a kd-tree's: the same neighbours, nearest first (equal
/// distances by point index).
class CellNeighbours {
public:
    /// `ordered`: keep a copy of the points in cell order (24 bytes a point), for grids queried
    /// often; without it every candidate is read from `pts` where it lies.
    CellNeighbours(const std::vector<Eigen::Vector3d>& pts, double cell_factor,
                   std::int64_t max_rings, bool ordered = true)
        : pts_(pts) {
        if (pts.empty()) return;
        const auto [lo, hi] = CellGrid::bounds(pts);
        Eigen::Vector3d ext = hi - lo;
        std::sort(ext.data(), ext.data() + 3);
        cell_ =
            cell_factor * std::sqrt(ext[2] * std::max(ext[1], 1e-3 * ext[2]) / double(pts.size()));
        ok_ = cell_ > 0.0 && std::isfinite(cell_) && grid_.build(pts, cell_, lo, hi);
        if (!ok_) return;
        max_rings_ = max_rings;
        const Eigen::Vector3d span = (hi - lo) / cell_;
        last_cell_ = {std::int64_t(span.x()) + 2, std::int64_t(span.y()) + 2,
                      std::int64_t(span.z()) + 2};
        // The points in cell order: a query reads its cells' points from one run of memory
        // instead of one cache miss per candidate across the whole cloud.
        if (!ordered) return;
        ordered_.resize(pts.size());
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pts.size(), 8192),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t a = r.begin(); a != r.end(); ++a)
                                  ordered_[a] = pts[grid_.point[a]];
                          });
    }
    /// Borrows `pts`: a temporary would be destroyed while the grid still points into it.
    CellNeighbours(std::vector<Eigen::Vector3d>&&, double, std::int64_t, bool = true) = delete;
    /// False when the grid could not be built (all points equal, an extent beyond 21 bits).
    bool ok() const { return ok_; }
    /// Side of a cell (m).
    double cell() const { return cell_; }
    /// Searches up to `max_rings` rings from now on (the same grid, another bound).
    void set_max_rings(std::int64_t max_rings) { max_rings_ = max_rings; }

    /// The k nearest points of q (k >= 1), nearest first, into indices / sq_dists (room for k
    /// each). Returns how many were found (k, or all points when there are fewer), or 0 when
    /// the search did not settle within max_rings rings. `bound_sq`: a squared distance known
    /// to be at least the k-th nearest's (knn_bound(): from any k points, such as a nearby
    /// query's neighbours): cells farther than it are skipped and the search ends once its
    /// rings reach it, which makes queries far from the points cheap. The result is the same;
    /// a bound that proves too small is dropped.
    std::size_t knn(const Eigen::Vector3d& q, std::size_t k, std::uint32_t* indices,
                    double* sq_dists,
                    double bound_sq = std::numeric_limits<double>::infinity()) const {
        const bool bounded = bound_sq < std::numeric_limits<double>::infinity();
        const Eigen::Vector3d& lo = grid_.lowest();
        // Distance along axis a from q to the cells of index i, their interval widened by a
        // millionth of a cell (a point's cell comes from a rounded division).
        const auto gap = [&](std::int64_t i, int a) {
            const double c0 = lo(a) + double(i - 2) * cell_ - 1e-6 * cell_;
            const double c1 = c0 + 1.000002 * cell_;
            return std::max({0.0, c0 - q(a), q(a) - c1});
        };
        std::size_t found = 0;
        const auto offer = [&](double d2, std::uint32_t j) {
            if (found == k &&
                !(d2 < sq_dists[k - 1] || (d2 == sq_dists[k - 1] && j < indices[k - 1])))
                return;
            std::size_t a = found < k ? found++ : k - 1;
            while (a > 0 &&
                   (sq_dists[a - 1] > d2 || (sq_dists[a - 1] == d2 && indices[a - 1] > j))) {
                sq_dists[a] = sq_dists[a - 1];
                indices[a] = indices[a - 1];
                --a;
            }
            sq_dists[a] = d2;
            indices[a] = j;
        };
        const auto visit = [&](std::int64_t x, std::int64_t y, std::int64_t z0, std::int64_t z1) {
            if (bounded) {  // only the column's cells that meet the ball of the bound
                const double gx = gap(x, 0), gy = gap(y, 1);
                const double rest = bound_sq - gx * gx - gy * gy;
                if (rest < 0.0) return;
                const double dz = std::sqrt(rest) / cell_;
                const double zq = (q.z() - lo.z()) / cell_ + 2.0;
                z0 = std::max(z0, std::int64_t(std::floor(zq - dz)) - 1);
                z1 = std::min(z1, std::int64_t(std::floor(zq + dz)) + 1);
                if (z0 > z1) return;
            }
            const auto [c0, c1] = grid_.column(x, y, z0, z1);
            if (!ordered_.empty())
                for (std::uint32_t a = grid_.start[c0]; a < grid_.start[c1]; ++a)
                    offer((ordered_[a] - q).squaredNorm(), grid_.point[a]);
            else
                for (std::uint32_t a = grid_.start[c0]; a < grid_.start[c1]; ++a) {
                    const std::uint32_t j = grid_.point[a];
                    offer((pts_[j] - q).squaredNorm(), j);
                }
        };
        if (!(((q - grid_.lowest()) / cell_).cwiseAbs().maxCoeff() < 1e15))
            return 0;  // no int64 cell
        const auto c = grid_.cell_of(q);
        // Rings past this one hold no cell: every point has been seen there.
        std::int64_t all_rings = 0;
        for (int a = 0; a < 3; ++a)
            all_rings = std::max({all_rings, c(a) - 2, last_cell_(a) - c(a)});
        if (all_rings > kMaxRings) return 0;  // far outside the grid: ask a kd-tree
        visit(c.x(), c.y(), c.z(), c.z());
        const std::size_t want = std::min(k, pts_.size());
        const std::int64_t rings = std::min(max_rings_, all_rings);
        for (std::int64_t ring = 1; ring <= rings; ++ring) {
            for (std::int64_t x = c.x() - ring; x <= c.x() + ring; ++x)
                for (std::int64_t y = c.y() - ring; y <= c.y() + ring; ++y) {
                    if (std::abs(x - c.x()) == ring || std::abs(y - c.y()) == ring) {
                        visit(x, y, c.z() - ring, c.z() + ring);
                    } else {
                        visit(x, y, c.z() - ring, c.z() - ring);
                        visit(x, y, c.z() + ring, c.z() + ring);
                    }
                }
            const double reach = double(ring) * cell_;
            // (Cells beyond the bound were skipped: settled only within it.)
            if (found == want && sq_dists[found - 1] <= reach * reach &&
                sq_dists[found - 1] <= bound_sq)
                return found;
            // Every point within the bound seen: the k nearest unless fewer than k lie within it
            // (a bound too small: searched again without it).
            if (bounded && reach * reach >= bound_sq * (1.0 + 1e-9))
                return found == want && sq_dists[found - 1] <= bound_sq
                           ? found
                           : knn(q, k, indices, sq_dists);
        }
        if (bounded && rings == all_rings && !(found == want && sq_dists[found - 1] <= bound_sq))
            return knn(q, k, indices, sq_dists);
        return rings == all_rings && found == want ? found : 0;
    }

private:
    static constexpr std::int64_t kMaxRings = 4096;
    const std::vector<Eigen::Vector3d>& pts_;
    std::vector<Eigen::Vector3d> ordered_;  ///< pts_ in the grid's cell order
    std::int64_t max_rings_ = 0;
    Eigen::Matrix<std::int64_t, 3, 1> last_cell_ = Eigen::Matrix<std::int64_t, 3, 1>::Zero();
    double cell_ = 0.0;
    bool ok_ = false;
    CellGrid grid_;
};

/// A bound for CellNeighbours::knn / PointSearch::knn of q with k = count: the largest squared
/// distance from q to the points pts[indices[0 .. count)] (any k points are at least as far as
/// the k-th nearest), computed as the searches compute distances; +inf when count is 0.
inline double knn_bound(const std::vector<Eigen::Vector3d>& pts, const std::uint32_t* indices,
                        std::size_t count, const Eigen::Vector3d& q) {
    if (count == 0) return std::numeric_limits<double>::infinity();
    double bound = 0.0;
    for (std::size_t j = 0; j < count; ++j)
        bound = std::max(bound, (pts[indices[j]] - q).squaredNorm());
    return bound;
}

/// Exact k nearest neighbours that always answers, for dense clouds queried a few hundred
/// thousand times (mesh vertices, surface samples): a fine cell grid (cells of twice the
/// surface spacing, 8 rings) settles the queries near the points, a coarse one (16 times the
/// spacing, every ring) those far from them, and a kd-tree is built only when neither grid can
/// be (an extent beyond 21 bits per axis) or for queries far outside the grid. Both grids keep
/// the points in cell order (48 bytes a point): on a noisy sequence one mesh vertex in eight
/// is farther than the fine grid's rings from its k-th neighbour, and a coarse cell holds
/// hundreds of points.
class PointSearch {
public:
    explicit PointSearch(const std::vector<Eigen::Vector3d>& pts)
        : pts_(pts),
          fine_(pts, 2.0, kFineRings),
          coarse_(pts, 16.0, std::numeric_limits<std::int64_t>::max()) {}
    /// Borrows `pts`: a temporary would be destroyed while the search still points into it.
    explicit PointSearch(std::vector<Eigen::Vector3d>&&) = delete;

    /// As CellNeighbours::knn (`bound_sq` included), but never 0 for a non-empty cloud. A
    /// bound beyond the fine grid's rings sends the query to the coarse grid at once.
    /// Thread-safe.
    std::size_t knn(const Eigen::Vector3d& q, std::size_t k, std::uint32_t* indices,
                    double* sq_dists,
                    double bound_sq = std::numeric_limits<double>::infinity()) const {
        if (pts_.empty() || k == 0) return 0;
        const double fine_reach = kFineRings * fine_.cell();
        if (fine_.ok() && !(bound_sq > fine_reach * fine_reach))
            if (const std::size_t found = fine_.knn(q, k, indices, sq_dists, bound_sq))
                return found;
        if (coarse_.ok())
            if (const std::size_t found = coarse_.knn(q, k, indices, sq_dists, bound_sq))
                return found;
        std::call_once(tree_once_, [&] { tree_ = std::make_unique<KdTree>(pts_); });
        return tree_->knn(q, k, indices, sq_dists);
    }

private:
    static constexpr std::int64_t kFineRings = 8;
    const std::vector<Eigen::Vector3d>& pts_;
    CellNeighbours fine_, coarse_;
    mutable std::once_flag tree_once_;
    mutable std::unique_ptr<KdTree> tree_;
};

}  // namespace rgbd::internal
