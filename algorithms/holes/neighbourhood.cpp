// The neighbourhood graphs of hole detection (docs/algorithms.md §10 step 1): directed
// kNN-or-radius lists of several option sets from one pass over a kd-tree, and their
// symmetrised compressed-row graphs. See also: hole_detection.cpp (the criteria).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <utility>

#include "algorithms/holes/hole_detection.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/neighbour_lists.hpp"

namespace rgbd::holes {

namespace detail {

std::vector<Directed> directed_lists(const std::vector<Eigen::Vector3d>& points,
                                     const internal::KdTree& tree, double spacing_m,
                                     const std::vector<NeighbourhoodOptions>& sets) {
    const std::size_t n = points.size(), m = sets.size();
    std::size_t k_max = 0;
    for (const auto& o : sets) k_max = std::max(k_max, std::size_t(o.k));
    constexpr std::size_t kChunk = 1024;
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    // rows[chunk * m + set]: the chunk's neighbours of that set; count[set][i].
    std::vector<std::vector<std::uint32_t>> rows(chunks * m);
    std::vector<std::vector<std::uint32_t>> count(m, std::vector<std::uint32_t>(n, 0));
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t chunk) {
        std::vector<std::uint32_t> idx(k_max + 2), own_idx(k_max + 2);
        std::vector<double> d2(k_max + 2), own_d2(k_max + 2);
        std::vector<std::pair<std::uint32_t, double>> within;
        std::vector<std::pair<double, std::uint32_t>> merged;
        const std::size_t end = std::min(n, (chunk + 1) * kChunk);
        for (std::size_t i = chunk * kChunk; i < end; ++i) {
            const std::size_t found = tree.knn(points[i], k_max + 1, idx.data(), d2.data());
            double shared_radius = -1;
            for (std::size_t s = 0; s < m; ++s) {
                const NeighbourhoodOptions& o = sets[s];
                const std::size_t cap = static_cast<std::size_t>(o.max_neighbours);
                const std::size_t want = std::size_t(o.k) + 1;
                merged.clear();
                const std::uint32_t* ki = idx.data();
                const double* kd = d2.data();
                std::size_t kn = std::min(found, want);
                if (want < found && d2[want - 1] == d2[want]) {
                    // A tie at the cut: which of the tied points a k-query keeps depends on
                    // the traversal; ask the tree exactly as a query of its own would.
                    kn = tree.knn(points[i], want, own_idx.data(), own_d2.data());
                    ki = own_idx.data();
                    kd = own_d2.data();
                }
                for (std::size_t j = 0; j < kn; ++j)
                    if (ki[j] != i) merged.emplace_back(kd[j], ki[j]);
                const double radius = o.radius_factor * spacing_m;
                if (radius > 0) {
                    if (radius != shared_radius) {
                        tree.radius(points[i], radius, within, /*sorted=*/false);
                        shared_radius = radius;
                    }
                    for (const auto& [j, dd] : within)
                        if (j != i) merged.emplace_back(dd, j);
                }
                std::sort(merged.begin(), merged.end());
                merged.erase(std::unique(merged.begin(), merged.end()), merged.end());
                std::vector<std::uint32_t>& row = rows[chunk * m + s];
                std::uint32_t c = 0;
                for (std::size_t j = 0; j < merged.size() && c < cap; ++j) {
                    if (j > 0 && merged[j].second == merged[j - 1].second) continue;
                    row.push_back(merged[j].second);
                    ++c;
                }
                count[s][i] = c;
            }
        }
    });
    std::vector<Directed> out(m);
    for (std::size_t s = 0; s < m; ++s) {
        Directed& d = out[s];
        d.offset.assign(n + 1, 0);
        for (std::size_t i = 0; i < n; ++i) d.offset[i + 1] = d.offset[i] + count[s][i];
        d.index.resize(d.offset[n]);
        tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t chunk) {
            std::vector<std::uint32_t>& row = rows[chunk * m + s];
            std::copy(row.begin(), row.end(), d.index.begin() + d.offset[chunk * kChunk]);
            std::vector<std::uint32_t>().swap(row);
        });
    }
    return out;
}

Neighbourhood graph_from(const Directed& directed, bool symmetric) {
    const std::size_t n = directed.offset.size() - 1;
    Neighbourhood graph;
    if (!symmetric) {
        graph.offset = directed.offset;
        graph.index = directed.index;
        return graph;
    }
    graph.offset.assign(n + 1, 0);
    for (std::size_t i = 0; i < n; ++i) {
        graph.offset[i + 1] += directed.offset[i + 1] - directed.offset[i];
        for (std::uint32_t e = directed.offset[i]; e < directed.offset[i + 1]; ++e)
            graph.offset[directed.index[e] + 1]++;
    }
    for (std::size_t i = 0; i < n; ++i) graph.offset[i + 1] += graph.offset[i];
    graph.index.resize(graph.offset[n]);
    std::vector<std::uint32_t> fill(graph.offset.begin(), graph.offset.end() - 1);
    for (std::size_t i = 0; i < n; ++i)
        for (std::uint32_t e = directed.offset[i]; e < directed.offset[i + 1]; ++e) {
            const std::uint32_t j = directed.index[e];
            graph.index[fill[i]++] = j;
            graph.index[fill[j]++] = static_cast<std::uint32_t>(i);
        }
    // Sort and deduplicate each row, then compact.
    std::vector<std::uint32_t> unique_count(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            auto b = graph.index.begin() + graph.offset[i];
            auto e = graph.index.begin() + graph.offset[i + 1];
            std::sort(b, e);
            unique_count[i] = static_cast<std::uint32_t>(std::unique(b, e) - b);
        }
    });
    std::size_t write = 0;
    std::uint32_t start = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t old_start = graph.offset[i];
        for (std::uint32_t c = 0; c < unique_count[i]; ++c)
            graph.index[write++] = graph.index[old_start + c];
        graph.offset[i] = start;
        start = static_cast<std::uint32_t>(write);
    }
    graph.offset[n] = start;
    graph.index.resize(write);
    graph.index.shrink_to_fit();
    return graph;
}

}  // namespace detail

Neighbourhood build_neighbourhood(const std::vector<Eigen::Vector3d>& points, double spacing_m,
                                  const NeighbourhoodOptions& options) {
    options.check();
    const internal::KdTree tree(points);
    return detail::graph_from(detail::directed_lists(points, tree, spacing_m, {options}).front(),
                              options.symmetric);
}

}  // namespace rgbd::holes
