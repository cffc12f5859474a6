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

// CGAL's repair first tries, for every region and round, angle smoothing of a copy of the region
// (twice: with and without its sharp edges constrained) before it cuts the region out and refills
// it. On a real capture's closure that attempt was 70-80% of the mesh stage (the APC shelf: 125 of
// 155 s; validation/results/2026-12-01-apc-fold-repair-profile.md) and on the synthetic objects
// it changed nothing the refill did not do. The repair here refills only; the regions still
// folded after it are smoothed once, in place (smooth_region), and refilled again.
#define CGAL_PMP_REMOVE_SELF_INTERSECTIONS_NO_SMOOTHING
#include <CGAL/Polygon_mesh_processing/angle_and_area_smoothing.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/box_intersection_d.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <set>
#include <string>

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
/// its holes refilled and caps flipped; the garbage is collected. `refilled` receives the holes
/// closed again.
void repair_faces(Mesh& mesh, const std::set<Mesh::Face_index>& involved, std::size_t& refilled) {
    const bool was_closed = CGAL::is_closed(mesh);
    // preserve_genus(false): an intersecting region may be removed with the handle it makes
    // (two sheets crossing are no handle of the surface the sensors saw).
    PMP::experimental::remove_self_intersections(
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

/// The faces `faces` and `rings` rings of faces round them (across vertices).
std::vector<Mesh::Face_index> ring_region(const Mesh& mesh, const std::set<Mesh::Face_index>& faces,
                                          int rings) {
    std::set<Mesh::Face_index> region = faces;
    std::vector<Mesh::Face_index> front(faces.begin(), faces.end()), next;
    for (int ring = 0; ring < rings; ++ring) {
        next.clear();
        for (auto f : front)
            for (auto v : mesh.vertices_around_face(mesh.halfedge(f)))
                for (auto g : mesh.faces_around_target(mesh.halfedge(v)))
                    if (g != Mesh::null_face() && region.insert(g).second) next.push_back(g);
        front.swap(next);
    }
    return {region.begin(), region.end()};
}

/// Angle smoothing (PMP::angle_and_area_smoothing, 100 iterations, no safety constraints, the
/// moves projected back onto the region's input triangles, Delaunay flips: what CGAL's repair
/// tries on a copy of a region before refilling it) of the faces `region`, in place. The
/// region's boundary edges are constrained, so no face outside it moves or changes.
void smooth_region(Mesh& mesh, const std::vector<Mesh::Face_index>& region) {
    std::vector<char> in(mesh.num_faces(), 0);
    for (auto f : region) in[std::size_t(f)] = 1;
    auto fixed = mesh.add_property_map<Mesh::Edge_index, bool>("e:rgbd_smooth_fixed", false).first;
    for (auto f : region)
        for (auto h : mesh.halfedges_around_face(mesh.halfedge(f))) {
            const auto g = mesh.face(mesh.opposite(h));
            if (g == Mesh::null_face() || !in[std::size_t(g)]) fixed[mesh.edge(h)] = true;
        }
    PMP::angle_and_area_smoothing(region, mesh,
                                  CGAL::parameters::number_of_iterations(100)
                                      .use_safety_constraints(false)
                                      .use_area_smoothing(false)
                                      .edge_is_constrained_map(fixed)
                                      .geom_traits(RepairTraits()));
    mesh.remove_property_map(fixed);
}

/// The number of crossing pairs of `mesh` with a face of `changed` in them (pairs of two other
/// faces are not looked at): the faces whose bounding box meets a changed face's
/// (CGAL::box_intersection_d), then CGAL's self_intersections among them and the changed faces.
std::size_t crossings_involving(const Mesh& mesh, const std::vector<Mesh::Face_index>& changed) {
    using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, Mesh::Face_index>;
    const auto box = [&](Mesh::Face_index f) {
        CGAL::Bbox_3 b;
        for (auto v : mesh.vertices_around_face(mesh.halfedge(f))) b += mesh.point(v).bbox();
        return Box(b, f);
    };
    std::vector<char> is_changed(mesh.num_faces(), 0), in_range(mesh.num_faces(), 0);
    std::vector<Box> mine, all;
    mine.reserve(changed.size());
    all.reserve(mesh.number_of_faces());
    for (auto f : changed) {
        mine.push_back(box(f));
        is_changed[std::size_t(f)] = in_range[std::size_t(f)] = 1;
    }
    for (auto f : mesh.faces()) all.push_back(box(f));
    CGAL::box_intersection_d(
        mine.begin(), mine.end(), all.begin(), all.end(),
        [&](const Box&, const Box& b) { in_range[std::size_t(b.info())] = 1; });
    std::vector<Mesh::Face_index> range;
    for (auto f : mesh.faces())
        if (in_range[std::size_t(f)]) range.push_back(f);
    FacePairs pairs;
    PMP::self_intersections<CGAL::Parallel_if_available_tag>(range, mesh,
                                                             std::back_inserter(pairs));
    return std::size_t(std::count_if(pairs.begin(), pairs.end(), [&](const auto& p) {
        return is_changed[std::size_t(p.first)] || is_changed[std::size_t(p.second)];
    }));
}

/// The pairs of faces of `patch` that cross a face of the same patch (a connected component of
/// `patch` across edges); `crossing` receives the number of crossing pairs among patch faces.
FacePairs folded_pairs(Mesh& mesh, const std::vector<Mesh::Face_index>& patch,
                       std::size_t* crossing = nullptr) {
    std::vector<std::size_t> component;
    components_within(mesh, patch, component);
    FacePairs pairs;
    PMP::self_intersections<CGAL::Parallel_if_available_tag>(patch, mesh,
                                                             std::back_inserter(pairs));
    if (crossing) *crossing = pairs.size();
    FacePairs folded;
    for (const auto& p : pairs)
        if (component[std::size_t(p.first)] == component[std::size_t(p.second)])
            folded.push_back(p);
    return folded;
}

/// Passes of smoothing then refilling after the first refill, at most.
constexpr int kSmoothingPasses = 3;

/// What refill_and_smooth did.
struct RepairPasses {
    std::size_t refilled = 0;             ///< holes closed again after a repair
    std::size_t smoothed = 0;             ///< faces smoothed, over the passes kept
    int passes = 0;                       ///< smoothing passes kept
    Report after_each = Report::array();  ///< pairs left after each refill
    FacePairs left;                       ///< the pairs left
};

/// CGAL's repair (refill only, see above) of the faces of `pairs`, then passes of: the pairs
/// `recount()` still finds, and two rings of faces round them, smoothed in place
/// (smooth_region), and the crossing faces refilled again. A pass is kept only if it leaves
/// fewer such pairs, and no more crossing pairs in the whole mesh than before it (smoothing moves
/// the faces round a fold too, which can then cross other parts; counted on the faces the pass
/// changed, crossings_involving); otherwise the mesh is put back as it was and the passes end
/// (at most kSmoothingPasses). `patch`, when given, is updated to its surviving faces and every
/// face the repairs add (internal::track_faces).
template <class Recount>
RepairPasses refill_and_smooth(Mesh& mesh, const FacePairs& pairs,
                               std::vector<Mesh::Face_index>* patch, const Recount& recount) {
    RepairPasses out;
    const auto refill = [&](const FacePairs& crossing) {
        std::size_t holes = 0;
        const std::set<Mesh::Face_index> involved = faces_of(crossing);
        const auto repair = [&] { repair_faces(mesh, involved, holes); };
        if (patch)
            internal::track_faces(mesh, *patch, repair);
        else
            repair();
        return holes;
    };
    if (pairs.empty()) return out;
    out.refilled = refill(pairs);
    // Counted again whatever CGAL reports: its verdict covers the regions it worked on, and a
    // crumpled patch it called repaired still crossed itself in 3 pairs (the cap flips after
    // it, or a refilled hole, can cross too).
    FacePairs now = recount();
    out.after_each.push_back(now.size());
    const std::string changed_name = "f:rgbd_pass_changed";
    while (!now.empty() && out.passes < kSmoothingPasses) {
        const std::vector<Mesh::Face_index> region = ring_region(mesh, faces_of(now), 2);
        // The faces a pass can change: the region, and (the map's default) every face it adds.
        auto changed = mesh.add_property_map<Mesh::Face_index, char>(changed_name, 1).first;
        for (auto f : mesh.faces()) changed[f] = 0;
        for (auto f : region) changed[f] = 1;
        const std::size_t crossings_before = crossings_involving(mesh, region);
        const Mesh before = mesh;
        std::vector<Mesh::Face_index> patch_before;
        if (patch) patch_before = *patch;
        // Smoothing moves vertices and flips edges only: the patch's faces stay its faces.
        smooth_region(mesh, region);
        FacePairs next = recount();
        std::size_t holes = 0;
        if (!next.empty()) {
            holes = refill(next);
            next = recount();
        }
        out.after_each.push_back(next.size());
        std::vector<Mesh::Face_index> changed_after;
        for (auto f : mesh.faces())
            if (changed[f]) changed_after.push_back(f);
        // Faces the refill removed round the region are not counted before: a pass that
        // removes crossings there is judged as if it had not.
        const bool kept = next.size() < now.size() &&
                          crossings_involving(mesh, changed_after) <= crossings_before;
        if (!kept) {
            mesh = before;
            if (patch) *patch = std::move(patch_before);
        }
        if (auto map = mesh.property_map<Mesh::Face_index, char>(changed_name); map.second)
            mesh.remove_property_map(map.first);
        if (!kept) break;
        ++out.passes;
        out.smoothed += region.size();
        out.refilled += holes;
        now = std::move(next);
    }
    out.left = std::move(now);
    return out;
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
    r["faces_involved"] = faces_of(pairs).size();
    r["faces_before"] = mesh.number_of_faces();
    const RepairPasses done =
        refill_and_smooth(mesh, pairs, nullptr, [&] { return self_intersecting_pairs(mesh); });
    r["faces_after"] = mesh.number_of_faces();
    r["pairs_after"] = done.left.size();
    r["holes_refilled"] = done.refilled;
    r["smoothing_passes"] = done.passes;
    r["faces_smoothed"] = done.smoothed;
    r["time_s"] = watch.seconds();
    return r;
}

Report repair_folded_patches(Mesh& mesh, std::vector<Mesh::Face_index>& patch) {
    const Stopwatch watch;
    Report r;
    std::size_t crossing = 0;
    const FacePairs folded = folded_pairs(mesh, patch, &crossing);
    const std::set<Mesh::Face_index> involved = faces_of(folded);
    // The regions CGAL's repair works on: the involved faces' components across edges.
    std::size_t regions = 0, largest_region = 0;
    if (!involved.empty()) {
        std::vector<std::size_t> region, size(components_within(mesh, involved, region), 0);
        for (auto f : involved) ++size[region[std::size_t(f)]];
        regions = std::size_t(std::count_if(size.begin(), size.end(), [](auto n) { return n; }));
        largest_region = *std::max_element(size.begin(), size.end());
    }
    r["patch_pairs"] = crossing;
    r["folded_pairs"] = folded.size();
    r["faces_involved"] = involved.size();
    r["regions"] = regions;
    r["largest_region_faces"] = largest_region;
    const RepairPasses done =
        refill_and_smooth(mesh, folded, &patch, [&] { return folded_pairs(mesh, patch); });
    r["holes_refilled"] = done.refilled;
    r["smoothing_passes"] = done.passes;
    r["faces_smoothed"] = done.smoothed;
    r["pairs_after_each_refill"] = done.after_each;
    r["pairs_after"] = done.left.size();
    r["time_s"] = watch.seconds();
    return r;
}

}  // namespace rgbd::reconstruction
