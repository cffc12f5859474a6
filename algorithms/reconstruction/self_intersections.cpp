#include "algorithms/reconstruction/self_intersections.hpp"

#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include "toolkit/types.hpp"

// CGAL's self-intersection repair cuts the faces round a crossing out and refills the hole with
// triangulate_hole_polyline, which searches the triangles of a 3D Delaunay triangulation of the
// hole's corners. That triangulation's cells and vertices are ordered by their addresses (which
// cell represents an edge, where the circulation round it starts, so which of two equally good
// triangles is taken): the repaired mesh followed the heap's layout (the jug, seed 2: 127,722 to
// 149,406 faces from the same points). CGAL 5.5 has no parameter for the triangulation it uses;
// its cell and vertex bases are specialised here, for a traits type of this translation unit's
// own, to carry time stamps, which the triangulation's containers order them by instead
// (creation order, as CGAL's Mesh_3 does). The search space and the result are CGAL's; only the
// order is fixed. (Turning the Delaunay search space off, CGAL_HOLE_FILLING_DO_NOT_USE_DT3, was
// deterministic too but made the repair fail more and cost more: the elephant left 375 crossing
// pairs instead of none, the APC shelf 376 s instead of 127.)
namespace rgbd::reconstruction {
namespace {
/// The kernel under a type of this translation unit's own: the hole filling's triangulation is
/// instantiated with it alone (and, in an unnamed namespace, with internal linkage).
struct RepairTraits : Kernel {};
}  // namespace
}  // namespace rgbd::reconstruction

namespace CGAL {

/// A time stamp for CGAL's compact containers, which order handles of a type with one by it.
class RepairTimeStamp {
public:
    using Has_timestamp = Tag_true;
    std::size_t time_stamp() const { return time_stamp_; }
    void set_time_stamp(const std::size_t& ts) { time_stamp_ = ts; }

private:
    std::size_t time_stamp_ = std::size_t(-1);
};

/// Delaunay_triangulation_cell_base_3 for RepairTraits, with a time stamp.
template <typename Cb>
class Delaunay_triangulation_cell_base_3<rgbd::reconstruction::RepairTraits, Cb>
    : public Cb, public RepairTimeStamp {
public:
    using Geom_traits = rgbd::reconstruction::RepairTraits;
    using Vertex_handle = typename Cb::Vertex_handle;
    using Cell_handle = typename Cb::Cell_handle;
    using Point_3 = typename Geom_traits::Point_3;
    using Point = Point_3;

    template <typename TDS2>
    struct Rebind_TDS {
        using Cb2 = typename Cb::template Rebind_TDS<TDS2>::Other;
        using Other = Delaunay_triangulation_cell_base_3<Geom_traits, Cb2>;
    };

    using Cb::Cb;

    template <typename GT_>
    Point_3 circumcenter(const GT_& gt) const {
        return gt.construct_circumcenter_3_object()(
            this->vertex(0)->point(), this->vertex(1)->point(), this->vertex(2)->point(),
            this->vertex(3)->point());
    }
    Point_3 circumcenter() const { return circumcenter(Geom_traits()); }
};

/// Triangulation_vertex_base_with_info_3 for RepairTraits, with a time stamp.
template <typename Info_, typename Vb>
class Triangulation_vertex_base_with_info_3<Info_, rgbd::reconstruction::RepairTraits, Vb>
    : public Vb, public RepairTimeStamp {
public:
    using Cell_handle = typename Vb::Cell_handle;
    using Point = typename Vb::Point;
    using Info = Info_;

    template <typename TDS2>
    struct Rebind_TDS {
        using Vb2 = typename Vb::template Rebind_TDS<TDS2>::Other;
        using Other =
            Triangulation_vertex_base_with_info_3<Info, rgbd::reconstruction::RepairTraits, Vb2>;
    };

    using Vb::Vb;

    const Info& info() const { return info_; }
    Info& info() { return info_; }

private:
    Info info_{};
};

}  // namespace CGAL

#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/boost/graph/helpers.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <set>

#include "algorithms/reconstruction/mesh_finishing.hpp"

namespace rgbd::reconstruction {

namespace PMP = CGAL::Polygon_mesh_processing;

namespace {

using FacePairs = std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>>;

/// The faces of the pairs, each once.
std::set<Mesh::Face_index> faces_of(const FacePairs& pairs) {
    std::set<Mesh::Face_index> faces;
    for (const auto& [a, b] : pairs) {
        faces.insert(a);
        faces.insert(b);
    }
    return faces;
}

/// CGAL's repair of the faces `involved` (they cross others), then, if the mesh was closed,
/// its holes refilled and caps flipped; the garbage is collected. Returns whether CGAL
/// reported success; `refilled` receives the holes closed again.
bool repair_faces(Mesh& mesh, const std::set<Mesh::Face_index>& involved, std::size_t& refilled) {
    const bool was_closed = CGAL::is_closed(mesh);
    // preserve_genus(false): an intersecting region may be removed with the handle it makes
    // (two sheets crossing are no handle of the surface the sensors saw).
    const bool repaired = PMP::experimental::remove_self_intersections(
        involved, mesh, CGAL::parameters::preserve_genus(false).geom_traits(RepairTraits()));
    refilled = 0;
    if (was_closed && !CGAL::is_closed(mesh)) {
        std::vector<Mesh::Halfedge_index> borders;
        PMP::extract_boundary_cycles(mesh, std::back_inserter(borders));
        for (auto h : borders) {
            if (!mesh.is_border(h)) continue;
            std::vector<Mesh::Face_index> faces;
            PMP::triangulate_refine_and_fair_hole(mesh, h, std::back_inserter(faces),
                                                  CGAL::Emptyset_iterator(),
                                                  CGAL::parameters::geom_traits(RepairTraits()));
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

/// The connected components of the faces `faces` across the edges between two of them: the
/// component id of each face of `faces`, indexed by std::size_t(face) (other faces get ids of
/// their own). Returns the number of ids.
template <class FaceRange>
std::size_t components_within(Mesh& mesh, const FaceRange& faces, std::vector<std::size_t>& id) {
    auto in = mesh.add_property_map<Mesh::Face_index, char>("f:rgbd_in_set", 0).first;
    for (auto f : faces) in[f] = 1;
    auto wall = mesh.add_property_map<Mesh::Edge_index, bool>("e:rgbd_set_wall", true).first;
    for (auto e : mesh.edges()) {
        const auto f = mesh.face(mesh.halfedge(e, 0)), g = mesh.face(mesh.halfedge(e, 1));
        wall[e] = f == Mesh::null_face() || g == Mesh::null_face() || !in[f] || !in[g];
    }
    auto component = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:rgbd_cc", 0).first;
    const std::size_t n =
        PMP::connected_components(mesh, component, CGAL::parameters::edge_is_constrained_map(wall));
    id.assign(mesh.num_faces(), 0);
    for (auto f : mesh.faces()) id[std::size_t(f)] = component[f];
    mesh.remove_property_map(component);
    mesh.remove_property_map(wall);
    mesh.remove_property_map(in);
    return n;
}

}  // namespace

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
    Report r = Report::object();
    r["self_intersecting_pairs"] = pairs.size();
    r["self_intersecting_faces"] = faces_of(pairs).size();
    return r;
}

Report repair_self_intersections(Mesh& mesh) {
    const Stopwatch watch;
    Report r;
    const auto pairs = self_intersecting_pairs(mesh);
    r["pairs_before"] = pairs.size();
    const std::set<Mesh::Face_index> involved = faces_of(pairs);
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
    // The patches: connected components across edges between two patch faces.
    std::vector<std::size_t> component;
    components_within(mesh, patch, component);
    FacePairs pairs;
    PMP::self_intersections<CGAL::Parallel_if_available_tag>(patch, mesh,
                                                             std::back_inserter(pairs));
    FacePairs folded;
    for (const auto& p : pairs)
        if (component[std::size_t(p.first)] == component[std::size_t(p.second)])
            folded.push_back(p);
    const std::set<Mesh::Face_index> involved = faces_of(folded);
    // The regions CGAL's repair works on: the involved faces' components across edges.
    std::size_t regions = 0, largest_region = 0;
    if (!involved.empty()) {
        std::vector<std::size_t> region, size(components_within(mesh, involved, region), 0);
        for (auto f : involved) ++size[region[std::size_t(f)]];
        regions = std::size_t(std::count_if(size.begin(), size.end(), [](auto n) { return n; }));
        largest_region = *std::max_element(size.begin(), size.end());
    }
    r["patch_pairs"] = pairs.size();
    r["folded_pairs"] = folded.size();
    r["faces_involved"] = involved.size();
    r["regions"] = regions;
    r["largest_region_faces"] = largest_region;
    std::size_t refilled = 0, after = 0;
    if (!involved.empty()) {
        // The faces the repair adds are patch faces too.
        bool repaired = true;
        internal::track_faces(mesh, patch,
                              [&] { repaired = repair_faces(mesh, involved, refilled); });
        if (!repaired || refilled > 0) {
            FacePairs left;
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
