#include "algorithms/denoise/cell_grid.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/spacing_sample.hpp"
#include "algorithms/sampling/robust_spacing.hpp"

namespace rgbd::denoise::detail {

bool eps_components(const std::vector<Eigen::Vector3d>& pts, double eps,
                    std::vector<std::uint32_t>& label) {
    const std::size_t m = pts.size();
    CellGrid grid;
    if (!grid.build(pts, eps / std::sqrt(3.0) * (1.0 - 1e-9))) return false;
    const auto& keyed = grid.keyed;
    const auto& keys = grid.keys;
    const auto& start = grid.start;
    const std::size_t cells = grid.cells();
    const double eps2 = eps * eps;
    detail::DisjointSets sets(cells);
    const auto linked = [&](std::size_t ca, std::size_t cb) {
        for (std::uint32_t i = start[ca]; i < start[ca + 1]; ++i)
            for (std::uint32_t j = start[cb]; j < start[cb + 1]; ++j)
                if ((pts[keyed[i].second] - pts[keyed[j].second]).squaredNorm() <= eps2)
                    return true;
        return false;
    };
    // In parallel: the pairs of cells that can hold a linked pair. Neighbours at most one cell
    // apart on every axis nearly always link, so they are tested here; the rest are only
    // listed, and tested below unless union-find already joined them.
    constexpr std::size_t kBlock = 512;
    const std::size_t blocks = (cells + kBlock - 1) / kBlock;
    std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> near_links(blocks),
        far_pairs(blocks);
    tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t blk) {
        for (std::size_t ca = blk * kBlock; ca < std::min(cells, (blk + 1) * kBlock); ++ca) {
            const std::uint64_t x = keys[ca] >> 42, y = (keys[ca] >> 21) & kKeyMask,
                                z = keys[ca] & kKeyMask;
            // Cells after this one in key order: (dx, dy) > (0, 0), or dx = dy = 0, dz > 0.
            for (int dx = 0; dx <= 2; ++dx)
                for (int dy = -2; dy <= 2; ++dy) {
                    if (dx == 0 && dy < 0) continue;
                    const int dz_min = dx == 0 && dy == 0 ? 1 : -2;
                    const auto [c0, c1] =
                        grid.column(std::int64_t(x) + dx, std::int64_t(y) + dy,
                                    std::int64_t(z) + dz_min, std::int64_t(z) + 2);
                    for (std::size_t cb = c0; cb < c1; ++cb) {
                        const int dz = int(std::int64_t(keys[cb] & kKeyMask) - std::int64_t(z));
                        const std::pair<std::uint32_t, std::uint32_t> pair{std::uint32_t(ca),
                                                                           std::uint32_t(cb)};
                        if (dx <= 1 && std::abs(dy) <= 1 && std::abs(dz) <= 1) {
                            if (linked(ca, cb)) near_links[blk].push_back(pair);
                        } else {
                            far_pairs[blk].push_back(pair);
                        }
                    }
                }
        }
    });
    for (const auto& block : near_links)
        for (const auto& [ca, cb] : block) sets.unite(ca, cb);
    for (const auto& block : far_pairs)
        for (const auto& [ca, cb] : block)
            if (sets.find(ca) != sets.find(cb) && linked(ca, cb)) sets.unite(ca, cb);
    label.assign(m, 0);
    for (std::size_t c = 0; c < cells; ++c) {
        const std::uint32_t root = sets.find(std::uint32_t(c));
        for (std::uint32_t i = start[c]; i < start[c + 1]; ++i) label[keyed[i].second] = root;
    }
    return true;
}

double grid_spacing(const std::vector<Eigen::Vector3d>& pts, std::size_t sample,
                    std::uint64_t seed) {
    const std::size_t n = pts.size();
    Eigen::Vector3d lo = pts[0], hi = pts[0];
    for (const auto& p : pts) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    Eigen::Vector3d ext = hi - lo;
    std::sort(ext.data(), ext.data() + 3);
    const double cell = std::sqrt(ext[2] * std::max(ext[1], 1e-3 * ext[2]) / double(n));
    CellGrid grid;
    if (!(cell > 0.0) || !grid.build(pts, cell)) return sampling::robust_spacing(pts, sample, seed);
    // Rings beyond the grid's extent hold no cells: the search is complete there.
    const Eigen::Vector3d span = (hi - lo) / cell;
    const std::int64_t all_rings = std::int64_t(span.maxCoeff()) + 2;
    // The median only needs the exact distances of the lower half: a query not settled
    // within kCapRings rings (an isolated outlier) is farther than kCapRings c from every other
    // point and gets that lower bound; the result is exact as long as fewer than half the
    // queries are capped (checked below; otherwise every ring is searched).
    constexpr std::int64_t kCapRings = 2;
    std::int64_t max_ring = std::min(all_rings, kCapRings);
    const std::vector<std::uint32_t> queries = internal::spacing_sample(n, sample, seed);
    std::vector<double> dist(queries.size(), 0.0);
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
    return internal::spacing_median(dist);
}

}  // namespace rgbd::denoise::detail
