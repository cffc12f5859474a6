#include "algorithms/denoise/eps_components.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/cell_grid.hpp"

namespace rgbd::denoise::detail {

using internal::CellGrid;
using internal::kKeyMask;

bool eps_components(const std::vector<Eigen::Vector3d>& pts, double eps,
                    std::vector<std::uint32_t>& label) {
    const std::size_t m = pts.size();
    CellGrid grid;
    if (!grid.build(pts, eps / std::sqrt(3.0) * (1.0 - 1e-9))) return false;
    const auto& point = grid.point;
    const auto& keys = grid.keys;
    const auto& start = grid.start;
    const std::size_t cells = grid.cells();
    const double eps2 = eps * eps;
    detail::DisjointSets sets(cells);
    const auto linked = [&](std::size_t ca, std::size_t cb) {
        for (std::uint32_t i = start[ca]; i < start[ca + 1]; ++i)
            for (std::uint32_t j = start[cb]; j < start[cb + 1]; ++j)
                if ((pts[point[i]] - pts[point[j]]).squaredNorm() <= eps2) return true;
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
        for (std::uint32_t i = start[c]; i < start[c + 1]; ++i) label[point[i]] = root;
    }
    return true;
}

}  // namespace rgbd::denoise::detail
