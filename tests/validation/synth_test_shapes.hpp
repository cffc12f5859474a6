// Analytic test shapes for the validation tests: a planar quad and an icosphere whose
// vertices lie on the sphere, as rgbd::Mesh. See also: validation/synth/rasterizer.hpp.
#pragma once

#include <Eigen/Core>
#include <array>
#include <map>
#include <utility>
#include <vector>

#include "toolkit/mesh.hpp"

namespace rgbd::synth::testing {

/// Appends a triangle soup to `mesh` (vertices in the same frame).
inline void append(Mesh& mesh, const std::vector<Eigen::Vector3d>& vertices,
                   const std::vector<std::array<int, 3>>& faces) {
    std::vector<Mesh::Vertex_index> ids;
    for (const auto& v : vertices) ids.push_back(mesh.add_vertex(to_point(v)));
    for (const auto& f : faces) mesh.add_face(ids[f[0]], ids[f[1]], ids[f[2]]);
}

/// A square of half-size `half` centred at `centre`, spanned by unit vectors a and b.
inline void add_quad(Mesh& mesh, const Eigen::Vector3d& centre, const Eigen::Vector3d& a,
                     const Eigen::Vector3d& b, double half) {
    append(mesh,
           {centre - half * a - half * b, centre + half * a - half * b,
            centre + half * a + half * b, centre - half * a + half * b},
           {{0, 1, 2}, {0, 2, 3}});
}

/// Icosphere: icosahedron subdivided `levels` times, vertices projected onto the sphere.
inline void add_icosphere(Mesh& mesh, const Eigen::Vector3d& centre, double radius, int levels) {
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                      {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                      {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (auto& p : v) p.normalize();
    std::vector<std::array<int, 3>> f = {
        {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
        {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
        {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<int, int>, int> mid;
        const auto midpoint = [&](int a, int b) {
            const auto key = std::minmax(a, b);
            const auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            v.push_back((v[a] + v[b]).normalized());
            return mid[key] = static_cast<int>(v.size()) - 1;
        };
        std::vector<std::array<int, 3>> g;
        for (const auto& tri : f) {
            const int ab = midpoint(tri[0], tri[1]), bc = midpoint(tri[1], tri[2]),
                      ca = midpoint(tri[2], tri[0]);
            g.push_back({tri[0], ab, ca});
            g.push_back({tri[1], bc, ab});
            g.push_back({tri[2], ca, bc});
            g.push_back({ab, bc, ca});
        }
        f = std::move(g);
    }
    for (auto& p : v) p = centre + radius * p;
    append(mesh, v, f);
}

/// An icosphere alone (20 * 4^levels faces), centred at `centre`.
inline Mesh icosphere(double radius, int levels,
                      const Eigen::Vector3d& centre = Eigen::Vector3d::Zero()) {
    Mesh mesh;
    add_icosphere(mesh, centre, radius, levels);
    return mesh;
}

/// A ball (icosphere of `levels` subdivisions, radius `radius`, centred at `ball`) in front of
/// a wall (a square of half-size `half` centred at `wall`, in the x-y plane): occluding edges,
/// a shadow and two depths for the rendering and noise tests.
inline Mesh ball_before_wall(const Eigen::Vector3d& wall, double half, const Eigen::Vector3d& ball,
                             double radius, int levels) {
    Mesh mesh;
    add_quad(mesh, wall, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), half);
    add_icosphere(mesh, ball, radius, levels);
    return mesh;
}

}  // namespace rgbd::synth::testing
