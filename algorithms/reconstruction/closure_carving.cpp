#include "algorithms/reconstruction/closure_carving.hpp"

#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

namespace rgbd::reconstruction::internal {

namespace PMP = CGAL::Polygon_mesh_processing;
using Halfedge = Mesh::Halfedge_index;

std::size_t orient_outward(Mesh& mesh) {
    auto component = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:rgbd_orient", 0).first;
    const std::size_t count = PMP::connected_components(mesh, component);
    std::vector<double> volume(count, 0.0);
    std::vector<char> open(count, 0);
    for (auto f : mesh.faces()) {
        const Halfedge h = mesh.halfedge(f);
        const Eigen::Vector3d a = to_eigen(mesh.point(mesh.source(h)));
        const Eigen::Vector3d b = to_eigen(mesh.point(mesh.target(h)));
        const Eigen::Vector3d c = to_eigen(mesh.point(mesh.target(mesh.next(h))));
        volume[component[f]] += a.dot(b.cross(c)) / 6.0;
        for (Halfedge x : CGAL::halfedges_around_face(h, mesh))
            if (mesh.is_border(mesh.opposite(x))) open[component[f]] = 1;
    }
    std::size_t reversed = 0;
    for (std::size_t k = 0; k < count; ++k) {
        if (open[k] || !(volume[k] < 0)) continue;
        std::vector<Mesh::Face_index> faces;
        for (auto f : mesh.faces())
            if (component[f] == k) faces.push_back(f);
        PMP::reverse_face_orientations(faces, mesh);
        ++reversed;
    }
    mesh.remove_property_map(component);
    return reversed;
}

std::size_t carve_patch(Mesh& mesh, const std::vector<Mesh::Face_index>& faces,
                        const std::vector<Mesh::Vertex_index>& vertices,
                        const SeenEmpty& seen_empty, int max_steps) {
    if (faces.size() < 20 || vertices.empty()) return 0;
    double length = 0;
    std::size_t edges = 0;
    for (auto f : faces)
        for (Halfedge h : CGAL::halfedges_around_face(mesh.halfedge(f), mesh)) {
            length += (to_eigen(mesh.point(mesh.source(h))) - to_eigen(mesh.point(mesh.target(h))))
                          .norm();
            ++edges;
        }
    const double step = 0.5 * length / static_cast<double>(std::max<std::size_t>(edges, 1));
    const std::size_t n = vertices.size();
    std::unordered_map<std::uint32_t, std::uint32_t> index;
    for (std::size_t i = 0; i < n; ++i) index.emplace(std::uint32_t(vertices[i]), std::uint32_t(i));
    // Neighbours inside the patch (-1: a rim vertex, depth 0), and the rim's points.
    std::vector<std::vector<std::int64_t>> around(n);
    std::vector<Eigen::Vector3d> base(n), direction(n), rim;
    for (std::size_t i = 0; i < n; ++i) {
        base[i] = to_eigen(mesh.point(vertices[i]));
        direction[i] = to_eigen(PMP::compute_vertex_normal(vertices[i], mesh));
        for (auto w : CGAL::vertices_around_target(mesh.halfedge(vertices[i]), mesh)) {
            const auto it = index.find(std::uint32_t(w));
            if (it == index.end()) rim.push_back(to_eigen(mesh.point(w)));
            around[i].push_back(it == index.end() ? -1 : std::int64_t(it->second));
        }
    }
    // The deepest a vertex may go: half its distance to the rim (a slope of 27 degrees from
    // the rim), so that a patch is dented, never pushed through the object it closes.
    std::vector<double> deepest(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        double nearest = std::numeric_limits<double>::infinity();
        for (const auto& q : rim) nearest = std::min(nearest, (q - base[i]).squaredNorm());
        deepest[i] = rim.empty() ? 0.0 : 0.5 * std::sqrt(nearest);
    }
    std::vector<double> depth(n, 0.0), smoothed(n);
    std::vector<char> empty(n, 0), moved(n, 0);
    for (int k = 0; k < max_steps; ++k) {
        tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
            empty[i] = depth[i] < deepest[i] && direction[i].allFinite() &&
                       direction[i].squaredNorm() > 0.5 &&
                       seen_empty(base[i] - depth[i] * direction[i], direction[i]);
        });
        if (std::find(empty.begin(), empty.end(), 1) == empty.end()) break;
        for (std::size_t i = 0; i < n; ++i)
            if (empty[i]) depth[i] += step, moved[i] = 1;
        // Smoothed over the patch (the rim holds at depth 0), never below the deepest.
        for (std::size_t i = 0; i < n; ++i) {
            if (around[i].empty()) {
                smoothed[i] = depth[i];
                continue;
            }
            double sum = 0;
            for (auto j : around[i]) sum += j < 0 ? 0.0 : depth[std::size_t(j)];
            smoothed[i] = std::min(
                deepest[i], 0.5 * depth[i] + 0.5 * sum / static_cast<double>(around[i].size()));
        }
        depth.swap(smoothed);
    }
    for (std::size_t i = 0; i < n; ++i)
        if (depth[i] > 0 && direction[i].allFinite())
            mesh.point(vertices[i]) = to_point(base[i] - depth[i] * direction[i]);
    return static_cast<std::size_t>(std::count(moved.begin(), moved.end(), 1));
}

}  // namespace rgbd::reconstruction::internal
