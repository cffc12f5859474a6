// Test data of the texture tests: a closed UV sphere about the origin, `rings` latitude bands
// (poles at z = +-radius(0) and +-radius(pi)) by `segments` longitudes, each vertex at
// radius(theta, phi) along its direction (theta from +z, phi from +x; metres), faces outward.
#pragma once

#include <cmath>
#include <vector>

#include "toolkit/mesh.hpp"

namespace rgbd::test {

template <typename Radius>
Mesh uv_sphere(int rings, int segments, Radius radius) {
    Mesh m;
    std::vector<Mesh::Vertex_index> v;
    const auto top = m.add_vertex(Point_3(0, 0, radius(0.0, 0.0)));
    for (int i = 1; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const double th = M_PI * i / rings, ph = 2 * M_PI * j / segments;
            const double r = radius(th, ph);
            v.push_back(m.add_vertex(Point_3(r * std::sin(th) * std::cos(ph),
                                             r * std::sin(th) * std::sin(ph), r * std::cos(th))));
        }
    const auto bottom = m.add_vertex(Point_3(0, 0, -radius(M_PI, 0.0)));
    auto at = [&](int i, int j) { return v[(i - 1) * segments + (j % segments)]; };
    for (int j = 0; j < segments; ++j) {
        m.add_face(top, at(1, j), at(1, j + 1));
        m.add_face(bottom, at(rings - 1, j + 1), at(rings - 1, j));
    }
    for (int i = 1; i + 1 < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            m.add_face(at(i, j), at(i + 1, j), at(i + 1, j + 1));
            m.add_face(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    return m;
}

}  // namespace rgbd::test
