#include "algorithms/reconstruction/advancing_front.hpp"

#include <CGAL/Advancing_front_surface_reconstruction.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/boost/graph/helpers.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

namespace rgbd::reconstruction::internal {

/// A triangulation vertex or cell base with a time stamp: CGAL's Compact_container then orders
/// handles by creation (the stamp) instead of by address. The triangulation's facet iterator
/// reports each facet from the side of the smaller cell handle, and the advancing front caches
/// a facet's Delaunay-sphere radius from the side it first sees (the two sides round
/// differently in the last bit): ordered by address, the same points gave different meshes in
/// different processes.
template <typename Base>
class Stamped : public Base {
public:
    using Has_timestamp = CGAL::Tag_true;
    template <typename TDS2>
    struct Rebind_TDS {
        using Other = Stamped<typename Base::template Rebind_TDS<TDS2>::Other>;
    };
    using Base::Base;
    std::size_t time_stamp() const { return stamp_; }
    void set_time_stamp(const std::size_t& stamp) { stamp_ = stamp; }

private:
    std::size_t stamp_ = std::size_t(-1);
};

using FrontTds = CGAL::Triangulation_data_structure_3<
    Stamped<CGAL::Advancing_front_surface_reconstruction_vertex_base_3<Kernel>>,
    Stamped<CGAL::Advancing_front_surface_reconstruction_cell_base_3<Kernel>>>;
using FrontDelaunay = CGAL::Delaunay_triangulation_3<Kernel, FrontTds>;
/// (priority, border edge) entries of the front's queue (`std::set` in CGAL 5.5).
using FrontQueueEntry = FrontTds::Vertex::Radius_ptr_type;

/// A candidate seed facet of the advancing front: its priority (finite), the facet (cell,
/// index) and its three corners, kept in the order of the triangulation's facet iterator.
struct FrontSeed {
    double value;
    FrontDelaunay::Cell_handle cell;
    int index;
    std::array<FrontDelaunay::Vertex_handle, 3> corners;
};

/// The seed facets ranked by priority (see the specialisation of the front's `init` below):
/// `list[next ..]` may still be free; `vertices` = the triangulation's vertices when ranked.
struct FrontSeeds {
    std::vector<FrontSeed> list;
    std::size_t next = 0;
    std::size_t vertices = 0;
};

/// Point indices {min, max} of the border edge a queue entry points at.
inline std::pair<std::size_t, std::size_t> edge_ids(const FrontQueueEntry& e) {
    const auto& edge = e.second->first.first;
    const std::size_t a = edge.first->vertex(edge.second)->id();
    const std::size_t b = edge.first->vertex(edge.third)->id();
    return std::minmax(a, b);
}

}  // namespace rgbd::reconstruction::internal

/// CGAL's advancing front keeps its border edges in a `std::set<std::pair<double, IO_edge*>>`
/// and so breaks ties in priority (every "stand-by" candidate has the same value, 3) by the
/// edges' heap addresses: the same points gave different meshes in different processes
/// (44,632 vs 44,633 vertices from byte-identical points whose file headers differed). Ties
/// are broken by the edge's point indices instead, which an entry keeps while it is queued
/// (the border element of edge (a, b) always describes edge (a, b)); the address decides only
/// between two entries of the same edge.
template <>
struct std::less<rgbd::reconstruction::internal::FrontQueueEntry> {
    bool operator()(const rgbd::reconstruction::internal::FrontQueueEntry& x,
                    const rgbd::reconstruction::internal::FrontQueueEntry& y) const {
        if (x.first < y.first) return true;
        if (y.first < x.first) return false;
        if (x.second == y.second) return false;
        const auto ix = rgbd::reconstruction::internal::edge_ids(x);
        const auto iy = rgbd::reconstruction::internal::edge_ids(y);
        if (ix != iy) return ix < iy;
        return std::less<const void*>()(x.second, y.second);
    }
};

namespace rgbd::reconstruction {
namespace {

namespace PMP = CGAL::Polygon_mesh_processing;

/// Advancing front's priority for the "front" method: CGAL's (radius of the smallest Delaunay
/// sphere) for triangles whose edges are at most max_edge and whose corners' normals agree with
/// each other and with the triangle; every other candidate is never taken.
struct FrontPriority {
    const std::vector<Eigen::Vector3d>* points;
    const std::vector<Eigen::Vector3d>* normals;
    double max_edge2;
    double cos_normal;  ///< corners' normals pairwise
    double cos_facet;   ///< triangle normal against the corners' mean normal
    /// The seed facets by priority, filled by the front's first seed search (see the
    /// specialisation of `init` below); shared by the copies CGAL makes of the functor.
    internal::FrontSeeds* seeds = nullptr;
    template <typename AdvancingFront, typename CellHandle>
    double operator()(const AdvancingFront& adv, CellHandle& c, const int& index) const {
        std::size_t id[3];
        for (int i = 0; i < 3; ++i) {
            const auto v = c->vertex((index + 1 + i) % 4);
            if (adv.triangulation_3().is_infinite(v)) return adv.infinity();
            id[i] = v->id();
        }
        const Eigen::Vector3d& a = (*points)[id[0]];
        const Eigen::Vector3d& b = (*points)[id[1]];
        const Eigen::Vector3d& d = (*points)[id[2]];
        if ((b - a).squaredNorm() > max_edge2 || (d - b).squaredNorm() > max_edge2 ||
            (a - d).squaredNorm() > max_edge2)
            return adv.infinity();
        const Eigen::Vector3d& na = (*normals)[id[0]];
        const Eigen::Vector3d& nb = (*normals)[id[1]];
        const Eigen::Vector3d& nd = (*normals)[id[2]];
        if (na.dot(nb) < cos_normal || nb.dot(nd) < cos_normal || nd.dot(na) < cos_normal)
            return adv.infinity();
        const Eigen::Vector3d f = (b - a).cross(d - a);
        const double fn = f.norm();
        const Eigen::Vector3d m = na + nb + nd;
        if (fn > 0 && std::abs(f.dot(m)) < cos_facet * fn * m.norm()) return adv.infinity();
        return adv.smallest_radius_delaunay_sphere(c, index);
    }
};

}  // namespace
}  // namespace rgbd::reconstruction

/// CGAL's advancing front looks for the seed of each new connected component by scanning
/// every facet of the triangulation (CGAL 5.5, `init`): with a few hundred components that was
/// most of the front's time (2 of 3.8 s on a 10-view ring). The same choice, found faster. The
/// scan takes, among the facets whose three corners are all outside the surface ("exterior"),
/// the first of least finite priority in the facet iterator's order (the first search: of all
/// facets). Here the facets it evaluates are ranked once, stably (ties in the iterator's
/// order, as the scan's strict `<`), and each search takes the first ranked facet whose
/// corners are all still exterior. That is the scan's choice because (1) a facet's priority
/// does not change while the triangulation does not: it is cached (the Delaunay-sphere radius,
/// from the side first asked) when the ranking evaluates it, at the moment and from the side
/// the scan would, and (2) a vertex never becomes exterior again while the triangulation does
/// not change (its mark is reset only for a vertex next to one being removed), so a facet
/// skipped once stays skipped (`next`). The post-processing removes vertices: when the
/// triangulation has fewer vertices than when ranked, the ranking is made again, over the
/// facets the scan would evaluate at that moment (all corners exterior).
template <>
bool CGAL::Advancing_front_surface_reconstruction<
    rgbd::reconstruction::internal::FrontDelaunay,
    rgbd::reconstruction::FrontPriority>::init(const bool& re_init) {
    init_timer.start();
    rgbd::reconstruction::internal::FrontSeeds& seeds = *priority.seeds;
    const auto exterior = [](const Cell_handle& c, int index) {
        return c->vertex((index + 1) & 3)->is_exterior() &&
               c->vertex((index + 2) & 3)->is_exterior() &&
               c->vertex((index + 3) & 3)->is_exterior();
    };
    if (!re_init || T.number_of_vertices() != seeds.vertices) {
        seeds.list.clear();
        seeds.next = 0;
        seeds.vertices = T.number_of_vertices();
        for (auto it = T.finite_facets_begin(); it != T.finite_facets_end(); ++it) {
            const Cell_handle c = it->first;
            const int index = it->second;
            if (re_init && !exterior(c, index)) continue;
            const coord_type value = priority(*this, c, index);
            if (!(value < infinity())) continue;  // never the minimum (nor NaN)
            seeds.list.push_back({value,
                                  c,
                                  index,
                                  {c->vertex((index + 1) & 3), c->vertex((index + 2) & 3),
                                   c->vertex((index + 3) & 3)}});
        }
        std::stable_sort(seeds.list.begin(), seeds.list.end(),
                         [](const auto& a, const auto& b) { return a.value < b.value; });
    }
    const rgbd::reconstruction::internal::FrontSeed* chosen = nullptr;
    for (; seeds.next < seeds.list.size(); ++seeds.next) {
        const auto& s = seeds.list[seeds.next];
        // The first search takes the minimum regardless of the corners (all are exterior then).
        if (!re_init || (s.corners[0]->is_exterior() && s.corners[1]->is_exterior() &&
                         s.corners[2]->is_exterior())) {
            chosen = &s;
            ++seeds.next;  // its corners are on the surface from now on
            break;
        }
    }
    if (chosen == nullptr) {
        init_timer.stop();
        return false;
    }
    // From here as CGAL's init: the seed's three edges start the new border.
    const Cell_handle c_min = chosen->cell;
    const int ind = chosen->index;
    const int i1 = (ind + 1) & 3, i2 = (ind + 2) & 3, i3 = (ind + 3) & 3;
    const Radius_edge_type e12 = compute_value(Edge_incident_facet(Edge(c_min, i1, i2), ind));
    const Radius_edge_type e23 = compute_value(Edge_incident_facet(Edge(c_min, i2, i3), ind));
    const Radius_edge_type e31 = compute_value(Edge_incident_facet(Edge(c_min, i3, i1), ind));
    IO_edge_type* p12 =
        set_border_elt(c_min->vertex(i1), c_min->vertex(i2), Border_elt(e12, _number_of_border));
    IO_edge_type* p23 =
        set_border_elt(c_min->vertex(i2), c_min->vertex(i3), Border_elt(e23, _number_of_border));
    IO_edge_type* p31 =
        set_border_elt(c_min->vertex(i3), c_min->vertex(i1), Border_elt(e31, _number_of_border));
    c_min->vertex(i1)->inc_mark();
    c_min->vertex(i2)->inc_mark();
    c_min->vertex(i3)->inc_mark();
    _ordered_border.insert(Radius_ptr_type(e12.first, p12));
    _ordered_border.insert(Radius_ptr_type(e23.first, p23));
    _ordered_border.insert(Radius_ptr_type(e31.first, p31));
    select_facet(c_min, ind);
    init_timer.stop();
    return true;
}

/// CGAL's `run` (5.5) without its last two steps, which the filtered front does not use:
/// `construct_surface` copies the selected facets into a 2D triangulation data structure and
/// `boundaries` walks its border loops (a tenth of a second after a 10-view ring's front, on the
/// one busy core). The triangles are read from the selected facets of the 3D triangulation
/// instead (selected_triangles()).
template <>
void CGAL::Advancing_front_surface_reconstruction<
    rgbd::reconstruction::internal::FrontDelaunay,
    rgbd::reconstruction::FrontPriority>::run(double radius_ratio_bound, double beta) {
    K = radius_ratio_bound;
    COS_BETA = std::cos(beta);
    if (T.dimension() < 3) return;
    initialize_vertices_and_cells();
    bool re_init = false;
    do {
        _number_of_connected_components++;
        if ((re_init = init(re_init))) {
            extend_timer.start();
            extend();
            extend_timer.stop();
            if ((number_of_facets() > static_cast<int>(T.number_of_vertices())) &&
                (NB_BORDER_MAX > 0)) {
                while (postprocessing()) {
                    extend2_timer.start();
                    extend();
                    extend2_timer.stop();
                }
            }
        }
    } while (re_init && ((_number_of_connected_components < max_connected_component) ||
                         (max_connected_component < 0)));
    clear_vertices();
}

namespace rgbd::reconstruction {
namespace {

/// The facets the advancing front selected (from either side), as point-index triples.
void selected_triangles(const internal::FrontDelaunay& dt,
                        std::vector<std::array<std::size_t, 3>>& triangles) {
    for (auto it = dt.finite_facets_begin(); it != dt.finite_facets_end(); ++it) {
        const auto c = it->first;
        const int ci = it->second;
        const auto n = c->neighbor(ci);
        const int ni = n->index(c);
        for (const auto& [cell, i] : {std::pair{c, ci}, std::pair{n, ni}})
            if (cell->is_selected_facet(i))
                triangles.push_back({cell->vertex((i + 1) & 3)->id(),
                                     cell->vertex((i + 2) & 3)->id(),
                                     cell->vertex((i + 3) & 3)->id()});
    }
}

}  // namespace

namespace internal {

void advancing_front(const std::vector<Eigen::Vector3d>& xyz,
                     const std::vector<Eigen::Vector3d>& normals, const FrontFilter* filter,
                     double radius_ratio_bound, double beta, Mesh& mesh) {
    std::vector<Point_3> points;
    points.reserve(xyz.size());
    for (const auto& p : xyz) points.push_back(to_point(p));
    std::vector<std::array<std::size_t, 3>> triangles;
    // As CGAL::advancing_front_surface_reconstruction(), on a triangulation whose handles are
    // ordered by creation (internal::Stamped) and whose front queue breaks ties by point index
    // (the std::less above): the same points give the same triangles in every process.
    std::vector<std::pair<Point_3, std::size_t>> indexed;
    indexed.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) indexed.emplace_back(points[i], i);
    internal::FrontDelaunay dt(indexed.begin(), indexed.end());
    if (filter) {
        internal::FrontSeeds seeds;
        const FrontPriority with_seeds{&xyz,
                                       &normals,
                                       filter->max_edge_m * filter->max_edge_m,
                                       std::cos(filter->max_normal_angle_deg * M_PI / 180.0),
                                       std::cos(filter->max_facet_angle_deg * M_PI / 180.0),
                                       &seeds};
        CGAL::Advancing_front_surface_reconstruction<internal::FrontDelaunay, FrontPriority> r(
            dt, with_seeds);
        r.run(radius_ratio_bound, beta);
        selected_triangles(dt, triangles);
    } else {
        CGAL::Advancing_front_surface_reconstruction<internal::FrontDelaunay> r(dt);
        r.run(radius_ratio_bound, beta);
        CGAL::write_triple_indices(std::back_inserter(triangles), r);
    }
    // Every triangle oriented along the mean input normal of its corners, then sorted, so that
    // the face order depends neither on the triangulation's storage nor on the order in which
    // the front reports a triangle's corners.
    for (auto& t : triangles) {
        const Eigen::Vector3d &a = xyz[t[0]], &b = xyz[t[1]], &c = xyz[t[2]];
        const Eigen::Vector3d n = normals[t[0]] + normals[t[1]] + normals[t[2]];
        if ((b - a).cross(c - a).dot(n) < 0) std::swap(t[1], t[2]);
        std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    }
    std::sort(triangles.begin(), triangles.end());
    // Make the soup consistently oriented (non-manifold vertices are duplicated) and build the
    // mesh. The triangles stay fixed-size arrays: a vector per triangle cost the sequential
    // tail an allocation and a free per face.
    PMP::repair_polygon_soup(points, triangles);
    PMP::orient_polygon_soup(points, triangles);
    PMP::polygon_soup_to_polygon_mesh(points, triangles, mesh);
    // orient_polygon_soup may flip whole components; restore agreement with the normals.
    if (CGAL::is_closed(mesh) && !PMP::is_outward_oriented(mesh))
        PMP::reverse_face_orientations(mesh);
}

}  // namespace internal
}  // namespace rgbd::reconstruction
