// Test helpers for results that must not depend on the heap's layout: a mesh as the list of its
// triangles' corner coordinates (face order, each face's corners from its halfedge), and a call
// run on a heap laid out differently from the test's own (CGAL's triangulations compare some
// handles by address: a result that followed them changed with the heap).
#pragma once

#include <CGAL/boost/graph/helpers.h>
#include <malloc.h>

#include <array>
#include <random>
#include <vector>

#include "toolkit/mesh.hpp"

namespace rgbd::test {

/// The corners of every face of `mesh`, in face order (x, y, z of each of the three corners).
inline std::vector<std::array<double, 9>> mesh_triangles(const Mesh& mesh) {
    std::vector<std::array<double, 9>> out;
    out.reserve(mesh.number_of_faces());
    for (auto f : mesh.faces()) {
        std::array<double, 9> t{};
        int k = 0;
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
            for (int i = 0; i < 3 && k < 9; ++i) t[k++] = mesh.point(v)[i];
        out.push_back(t);
    }
    return out;
}

/// Runs `call` on a heap laid out the other way round: every block of 4 KiB or more mapped on
/// its own (glibc maps them top-down), the small ones around scrambled free lists. Returns what
/// `call` returns.
template <class Call>
auto on_scrambled_heap(Call&& call) {
    std::vector<std::vector<char>> kept, dropped;
    std::mt19937 rng(7);
    for (int i = 0; i < 4000; ++i) (i % 3 ? kept : dropped).emplace_back(16 + rng() % 4000, 'x');
    dropped.clear();
    mallopt(M_MMAP_THRESHOLD, 4096);
    struct Restore {
        ~Restore() { mallopt(M_MMAP_THRESHOLD, 128 * 1024); }
    } restore;
    return call();
}

}  // namespace rgbd::test
