#include "algorithms/reconstruction/self_intersections.hpp"

#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/shape_predicates.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/boost/graph/helpers.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <set>

#include "toolkit/error.hpp"

namespace rgbd::reconstruction {

namespace PMP = CGAL::Polygon_mesh_processing;

std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> self_intersecting_pairs(
    const Mesh& mesh) {
    std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
    PMP::self_intersections<CGAL::Parallel_if_available_tag>(mesh, std::back_inserter(pairs));
    for (auto& p : pairs)
        if (p.second < p.first) std::swap(p.first, p.second);
    std::sort(pairs.begin(), pairs.end());
    return pairs;
}

Report self_intersection_counts(const Mesh& mesh) {
    const auto pairs = self_intersecting_pairs(mesh);
    std::set<Mesh::Face_index> faces;
    for (const auto& p : pairs) {
        faces.insert(p.first);
        faces.insert(p.second);
    }
    Report r = Report::object();
    r["self_intersecting_pairs"] = pairs.size();
    r["self_intersecting_faces"] = faces.size();
    return r;
}

namespace {

/// CGAL's repair of the faces `involved` (they cross others), then, if the mesh was closed,
/// its holes refilled and caps flipped; the garbage is collected. Returns whether CGAL
/// reported success; `refilled` receives the holes closed again.
bool repair_faces(Mesh& mesh, const std::set<Mesh::Face_index>& involved, std::size_t& refilled) {
    const bool was_closed = CGAL::is_closed(mesh);
    // preserve_genus(false): an intersecting region may be removed with the handle it makes
    // (two sheets crossing are no handle of the surface the sensors saw).
    const bool repaired = PMP::experimental::remove_self_intersections(
        involved, mesh, CGAL::parameters::preserve_genus(false));
    refilled = 0;
    if (was_closed && !CGAL::is_closed(mesh)) {
        std::vector<Mesh::Halfedge_index> borders;
        PMP::extract_boundary_cycles(mesh, std::back_inserter(borders));
        for (auto h : borders) {
            if (!mesh.is_border(h)) continue;
            std::vector<Mesh::Face_index> faces;
            PMP::triangulate_refine_and_fair_hole(mesh, h, std::back_inserter(faces),
                                                  CGAL::Emptyset_iterator());
            refilled += !faces.empty();
        }
    }
    // The refilled regions can hold a cap, a triangle with an angle near 180 degrees (a
    // border vertex near its neighbours' midpoint): written in single precision (PLY), its
    // corners become collinear and it intersects its neighbours by CGAL's and Open3D's
    // rules. Its longest edge is flipped (no needles are touched).
    PMP::experimental::remove_almost_degenerate_faces(mesh, std::cos(179.0 * M_PI / 180.0),
                                                      std::numeric_limits<double>::max(), 0.0);
    mesh.collect_garbage();
    return repaired;
}

}  // namespace

Report repair_self_intersections(Mesh& mesh) {
    const Stopwatch watch;
    Report r;
    const auto pairs = self_intersecting_pairs(mesh);
    r["pairs_before"] = pairs.size();
    std::set<Mesh::Face_index> involved;
    for (const auto& p : pairs) {
        involved.insert(p.first);
        involved.insert(p.second);
    }
    r["faces_involved"] = involved.size();
    r["faces_before"] = mesh.number_of_faces();
    std::size_t after = 0, refilled = 0;
    if (!pairs.empty()) {
        const bool repaired = repair_faces(mesh, involved, refilled);
        // CGAL's verdict covers the faces it worked on; a refilled hole is checked again.
        if (!repaired || refilled > 0) after = self_intersecting_pairs(mesh).size();
    }
    r["faces_after"] = mesh.number_of_faces();
    r["pairs_after"] = after;
    r["holes_refilled"] = refilled;
    r["time_s"] = watch.seconds();
    return r;
}

Report repair_folded_patches(Mesh& mesh, std::vector<Mesh::Face_index>& patch) {
    const Stopwatch watch;
    Report r;
    // The patches: components of the patch faces across shared edges (union-find by slot).
    std::vector<std::size_t> parent(mesh.num_faces(), static_cast<std::size_t>(-1));
    for (auto f : patch) parent[std::size_t(f)] = std::size_t(f);
    auto root = [&parent](std::size_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    for (auto f : patch)
        for (auto h : CGAL::halfedges_around_face(mesh.halfedge(f), mesh)) {
            const auto g = mesh.face(mesh.opposite(h));
            if (g == Mesh::null_face() || parent[std::size_t(g)] == static_cast<std::size_t>(-1))
                continue;
            const std::size_t a = root(std::size_t(f)), b = root(std::size_t(g));
            if (a != b) parent[std::max(a, b)] = std::min(a, b);
        }
    std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
    PMP::self_intersections<CGAL::Parallel_if_available_tag>(patch, mesh,
                                                             std::back_inserter(pairs));
    std::set<Mesh::Face_index> involved;
    std::size_t folded = 0;
    for (const auto& [a, b] : pairs)
        if (root(std::size_t(a)) == root(std::size_t(b))) {
            ++folded;
            involved.insert(a);
            involved.insert(b);
        }
    r["patch_pairs"] = pairs.size();
    r["folded_pairs"] = folded;
    r["faces_involved"] = involved.size();
    std::size_t refilled = 0, after = 0;
    if (!involved.empty()) {
        // The patch faces, and the faces the repair adds (new faces take the map's default),
        // survive the garbage collection in a property map.
        auto added = mesh.add_property_map<Mesh::Face_index, char>("f:rgbd_repair_patch", 1).first;
        for (auto f : mesh.faces()) added[f] = 0;
        for (auto f : patch) added[f] = 1;
        const bool repaired = repair_faces(mesh, involved, refilled);
        patch.clear();
        for (auto f : mesh.faces())
            if (added[f]) patch.push_back(f);
        mesh.remove_property_map(added);
        if (!repaired || refilled > 0) {
            std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> left;
            PMP::self_intersections(patch, mesh, std::back_inserter(left));
            after = left.size();
        }
    }
    r["holes_refilled"] = refilled;
    r["pairs_after"] = after;
    r["time_s"] = watch.seconds();
    return r;
}

}  // namespace rgbd::reconstruction
