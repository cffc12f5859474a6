// The cell grid of the density filter's neighbour searches (docs/algorithms.md, density-based
// cleaning): points binned in cubic cells with 21-bit keys per axis, the exact components of
// the eps graph over a point set, and the robust spacing with grid nearest neighbours. Internal
// to algorithms/denoise (not installed).
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace rgbd::denoise::detail {

/// Key of cell (x, y, z), 21 bits per axis.
constexpr std::uint64_t key_of(std::uint64_t x, std::uint64_t y, std::uint64_t z) {
    return (x << 42) | (y << 21) | z;
}
constexpr std::uint64_t kKeyMask = (std::uint64_t(1) << 21) - 1;

/// Points binned in cubic cells of side `cell` (cell coordinates offset by 2, so that
/// neighbour offsets -2..2 never underflow), sorted by cell key.
struct CellGrid {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;  ///< (cell key, point), sorted
    std::vector<std::uint64_t> keys;                             ///< unique cell keys, sorted
    std::vector<std::uint32_t> start;  ///< cell c's points: keyed[start[c], start[c + 1])

    /// False (grid left empty) when the extent needs more than 21 bits per axis.
    bool build(const std::vector<Eigen::Vector3d>& pts, double cell) {
        const std::size_t m = pts.size();
        if (!(cell > 0.0) || m == 0) return false;
        Eigen::Vector3d lo = pts[0], hi = pts[0];
        for (const auto& p : pts) {
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
        constexpr double kMaxCells = double(1 << 21) - 8.0;
        if (((hi - lo) / cell).maxCoeff() >= kMaxCells) return false;
        origin = lo;
        side = cell;
        keyed.resize(m);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m, 4096),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t a = r.begin(); a != r.end(); ++a) {
                                  const Eigen::Vector3d c = (pts[a] - lo) / cell;
                                  keyed[a] = {
                                      key_of(std::uint64_t(c.x()) + 2, std::uint64_t(c.y()) + 2,
                                             std::uint64_t(c.z()) + 2),
                                      std::uint32_t(a)};
                              }
                          });
        sort_keyed(hi - lo, cell);
        for (std::size_t a = 0; a < m; ++a)
            if (a == 0 || keyed[a].first != keyed[a - 1].first) {
                keys.push_back(keyed[a].first);
                start.push_back(std::uint32_t(a));
            }
        start.push_back(std::uint32_t(m));
        // Dense column index when it is small next to the points (it nearly always is for
        // surfaces): column (x, y)'s cells are keys[column_start[x ny + y], ... + 1]).
        const Eigen::Vector3d span = (hi - lo) / cell;
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
    std::size_t cells() const { return keys.size(); }
    /// Grid coordinates of the cell holding p (offset included), as build() assigns them.
    Eigen::Matrix<std::int64_t, 3, 1> cell_of(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d c = (p - origin) / side;
        return {std::int64_t(c.x()) + 2, std::int64_t(c.y()) + 2, std::int64_t(c.z()) + 2};
    }

    /// Sorts `keyed` by (key, point). When the grid has fewer than 2^32 cells, a stable LSD
    /// radix sort of the linear cell index (x ny + y) nz + z, which orders cells as the keys
    /// do (3 passes of 11 bits); else a comparison sort.
    void sort_keyed(const Eigen::Vector3d& extent, double cell) {
        const Eigen::Vector3d span = extent / cell;
        const double lx = std::floor(span.x()) + 5, ly = std::floor(span.y()) + 5,
                     lz = std::floor(span.z()) + 5;
        if (lx * ly * lz >= 4294967295.0) {
            tbb::parallel_sort(keyed.begin(), keyed.end());
            return;
        }
        const std::uint64_t my = std::uint64_t(ly), mz = std::uint64_t(lz);
        const std::size_t m = keyed.size();
        std::vector<std::pair<std::uint32_t, std::uint32_t>> a(m), b(m);
        for (std::size_t i = 0; i < m; ++i) {
            const std::uint64_t k = keyed[i].first;
            a[i] = {std::uint32_t(((k >> 42) * my + ((k >> 21) & kKeyMask)) * mz + (k & kKeyMask)),
                    keyed[i].second};
        }
        constexpr int kBits = 11;
        constexpr std::uint32_t kBuckets = 1u << kBits;
        std::vector<std::uint32_t> count(kBuckets);
        for (int shift = 0; shift < 32; shift += kBits) {
            std::fill(count.begin(), count.end(), 0u);
            for (const auto& e : a) ++count[(e.first >> shift) & (kBuckets - 1)];
            std::uint32_t sum = 0;
            for (auto& c : count) {
                const std::uint32_t c0 = c;
                c = sum;
                sum += c0;
            }
            for (const auto& e : a) b[count[(e.first >> shift) & (kBuckets - 1)]++] = e;
            a.swap(b);
        }
        // Points are in increasing order within a cell (stable passes over an input in
        // point order), as the comparison sort of (key, point) leaves them.
        std::vector<std::uint64_t> key_of_point(m);
        for (const auto& e : keyed) key_of_point[e.second] = e.first;
        for (std::size_t i = 0; i < m; ++i) keyed[i] = {key_of_point[a[i].second], a[i].second};
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

/// Components of the eps graph over `pts` (p ~ q iff |p - q| <= eps), exactly, without a
/// radius search per point: points are binned in cells of side c = eps / sqrt(3) (any two
/// points of a cell are closer than eps, so a cell lies in one component) and only cells at
/// most 2 apart on every axis can hold a linked pair (3 cells apart means more than 2c > eps
/// on that axis); a pair of cells is tested point by point, stopping at the first link, and
/// skipped when both already share a component. Writes each point's component
/// label (a cell index, equal for the points of one component) to `label`. Returns false
/// without touching `label` when the grid would not fit 21 bits per axis.
bool eps_components(const std::vector<Eigen::Vector3d>& pts, double eps,
                    std::vector<std::uint32_t>& label);

/// sampling::robust_spacing(pts, sample, seed), exactly (same query sample, nearest other
/// point, same median), with the nearest neighbours found on a cell grid instead of a kd-tree:
/// cells of side c ~ the spacing a surface over the bounding box's largest face would have;
/// rings of cells around the query's are searched until the best distance is at most R c
/// after ring R (any point outside ring R is farther than R c), or all rings are searched. Falls
/// back to the kd-tree for extents the grid cannot hold.
double grid_spacing(const std::vector<Eigen::Vector3d>& pts, std::size_t sample,
                    std::uint64_t seed);

}  // namespace rgbd::denoise::detail
