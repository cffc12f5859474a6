#include "algorithms/reconstruction/reconstruct_surface.hpp"

#include <CGAL/Advancing_front_surface_reconstruction.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Random.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/compute_average_spacing.h>
#include <CGAL/property_map.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "algorithms/holes/free_space.hpp"
#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/poisson_solver.hpp"
#include "algorithms/reconstruction/closure_carving.hpp"
#include "algorithms/reconstruction/mesh_colour.hpp"
#include "algorithms/reconstruction/mesh_finishing.hpp"
#include "algorithms/reconstruction/point_budget.hpp"
#include "algorithms/reconstruction/self_intersections.hpp"
#include "algorithms/reconstruction/smooth_points.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "algorithms/sampling/voxel_downsample.hpp"
#include "toolkit/error.hpp"
#include "toolkit/wait_at_exit.hpp"

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

namespace PMP = CGAL::Polygon_mesh_processing;

void ReconstructionOptions::check() const {
    RGBD_CHECK(method == "front" || method == "poisson" || method == "advancing-front",
               "reconstruction: unknown method '" + method +
                   "' (use 'front', 'poisson' or 'advancing-front')");
    RGBD_CHECK(target_faces == 0 || (target_faces >= 4 && target_faces <= 2000000000u),
               "reconstruction: target_faces must be 0 (keep) or in [4, 2e9], got " +
                   std::to_string(target_faces));
    check_range("reconstruction: min_component_fraction", min_component_fraction,
                Range::closed(0, 1));
    check_range("reconstruction: smooth_radius", smooth_radius, Range::open_closed(0, 50),
                "x spacing");
    check_range("reconstruction: smooth_iterations", smooth_iterations, Range::closed(0, 10));
    check_range("reconstruction: front_voxel", front_voxel, Range::closed(0, 20), "x spacing");
    check_range("reconstruction: front_max_edge", front_max_edge, Range::open_closed(0, 1000),
                "x spacing");
    check_range("reconstruction: front_max_normal_angle_deg", front_max_normal_angle_deg,
                Range::open_closed(0, 180));
    check_range("reconstruction: front_max_facet_angle_deg", front_max_facet_angle_deg,
                Range::open_closed(0, 90));
    RGBD_CHECK(max_points == 0 || max_points >= 100,
               "reconstruction: max_points must be 0 or >= 100");
    check_range("reconstruction: seen_through_max", seen_through_max, Range::closed(0, 1));
    check_range("reconstruction: carve_steps", carve_steps, Range::closed(0, 1000), "steps");
    check_range("reconstruction: carve_votes", carve_votes, Range::closed(1, 1000), "sensors");
    RGBD_CHECK(fair_max_edges >= 3, "reconstruction: fair_max_edges must be at least 3");
    check_range("reconstruction: ground_margin_m", ground_margin_m, Range::closed_open(0, 1), "m");
    RGBD_CHECK(!ground || ground->allFinite(), "reconstruction: the ground plane must be finite");
    check_range("reconstruction: sm_angle_deg", sm_angle_deg, Range::open_closed(0, 30));
    check_range("reconstruction: sm_radius", sm_radius, Range::open(0, 1e4));
    check_range("reconstruction: sm_distance", sm_distance, Range::open(0, 100));
    RGBD_CHECK(!up || (up->allFinite() && up->norm() > 0),
               "reconstruction: the up direction must be a finite non-zero vector");
    RGBD_CHECK(af_radius_ratio_bound > 0, "reconstruction: af_radius_ratio_bound must be > 0");
    RGBD_CHECK(af_beta > 0 && af_beta < M_PI, "reconstruction: af_beta must be in (0, pi)");
    check_range("reconstruction: fold_angle_deg", fold_angle_deg, Range::open_closed(0, 180));
    check_range("reconstruction: spike_angle_deg", spike_angle_deg, Range::closed_open(0, 60));
    check_range("reconstruction: color_k", color_k, Range::closed(1, 256));
    RGBD_CHECK(color_original_radius >= 0, "reconstruction: color_original_radius must be >= 0");
}

namespace {

using Pwn = std::pair<Point_3, Vector_3>;

using PointOf = CGAL::First_of_pair_property_map<Pwn>;

std::string view_name(const PointCloud& cloud) { return "view " + std::to_string(cloud.view.id); }

/// CGAL's default random generator is seeded from the clock (CGAL::Random(), whole seconds).
/// The surface mesher draws its initial points from it, and the Delaunay hole triangulation
/// shuffles the hole's corners with it (spatial_sort), which decides between equally valid
/// triangulations of cospherical corners. Seeded for the scope: the same input gives the same
/// mesh in every process; the caller's generator is restored afterwards.
class ScopedDefaultRandom {
public:
    explicit ScopedDefaultRandom(unsigned seed) : saved_(CGAL::get_default_random()) {
        CGAL::get_default_random() = CGAL::Random(seed);
    }
    ~ScopedDefaultRandom() { CGAL::get_default_random() = saved_; }
    ScopedDefaultRandom(const ScopedDefaultRandom&) = delete;
    ScopedDefaultRandom& operator=(const ScopedDefaultRandom&) = delete;

private:
    CGAL::Random saved_;
};

void poisson(const std::vector<Pwn>& pwn, double spacing, const ReconstructionOptions& o,
             Mesh& mesh) {
    const ScopedDefaultRandom seeded(0);
    if (!rgbd::internal::poisson_surface(pwn, spacing, o.sm_angle_deg, o.sm_radius, o.sm_distance,
                                         mesh))
        throw AlgorithmError("reconstruction: the Poisson solver failed");
}

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

/// Advancing front over points with unit normals; `priority` null = CGAL's default.
void advancing_front(const std::vector<Eigen::Vector3d>& xyz,
                     const std::vector<Eigen::Vector3d>& normals, const FrontPriority* priority,
                     const ReconstructionOptions& o, Mesh& mesh) {
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
    if (priority) {
        internal::FrontSeeds seeds;
        FrontPriority with_seeds = *priority;
        with_seeds.seeds = &seeds;
        CGAL::Advancing_front_surface_reconstruction<internal::FrontDelaunay, FrontPriority> r(
            dt, with_seeds);
        r.run(o.af_radius_ratio_bound, o.af_beta);
        selected_triangles(dt, triangles);
    } else {
        CGAL::Advancing_front_surface_reconstruction<internal::FrontDelaunay> r(dt);
        r.run(o.af_radius_ratio_bound, o.af_beta);
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

/// Averages points and normals per voxel of edge `voxel`, separately for the six dominant
/// normal directions (the two sides of a part thinner than a voxel stay apart).
void thin_by_voxel(std::vector<Eigen::Vector3d>& xyz, std::vector<Eigen::Vector3d>& normals,
                   double voxel) {
    if (voxel <= 0 || xyz.empty()) return;
    Eigen::Vector3d lo = xyz.front();
    for (const auto& p : xyz) lo = lo.cwiseMin(p);
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keys(xyz.size());
    tbb::parallel_for(std::size_t(0), xyz.size(), [&](std::size_t i) {
        const Eigen::Vector3d g = ((xyz[i] - lo) / voxel).array().floor();
        int axis;
        normals[i].cwiseAbs().maxCoeff(&axis);
        const std::uint64_t side = static_cast<std::uint64_t>(2 * axis + (normals[i][axis] < 0));
        const std::uint64_t key = (static_cast<std::uint64_t>(g.x()) & 0x1FFFFF) |
                                  ((static_cast<std::uint64_t>(g.y()) & 0x1FFFFF) << 21) |
                                  ((static_cast<std::uint64_t>(g.z()) & 0x1FFFFF) << 42);
        keys[i] = {key * 6 + side, static_cast<std::uint32_t>(i)};
    });
    std::sort(keys.begin(), keys.end());
    std::vector<Eigen::Vector3d> out_p, out_n;
    for (std::size_t i = 0; i < keys.size();) {
        std::size_t j = i;
        Eigen::Vector3d p = Eigen::Vector3d::Zero(), n = Eigen::Vector3d::Zero();
        for (; j < keys.size() && keys[j].first == keys[i].first; ++j) {
            p += xyz[keys[j].second];
            n += normals[keys[j].second];
        }
        out_p.push_back(p / static_cast<double>(j - i));
        out_n.push_back(n.squaredNorm() > 1e-24 ? n.normalized() : normals[keys[i].second]);
        i = j;
    }
    xyz.swap(out_p);
    normals.swap(out_n);
}

/// The points the filtered front goes through: the input projected onto its MLS surface
/// (smooth_points), then thinned to a grid of o.front_voxel spacings.
void front_points(std::vector<Eigen::Vector3d>& xyz, std::vector<Eigen::Vector3d>& normals,
                  double spacing, const ReconstructionOptions& o, Report& r) {
    Stopwatch watch;
    internal::SmoothOptions so;
    so.radius = o.smooth_radius * spacing;
    so.iterations = o.smooth_iterations;
    std::size_t moved = 0;
    if (o.smooth_iterations > 0) moved = internal::smooth_points(xyz, normals, so);
    r["smoothed_points"] = moved;
    r["smooth_radius_m"] = so.radius;
    r["smooth_time_s"] = watch.seconds();
    thin_by_voxel(xyz, normals, o.front_voxel * spacing);
    r["front_points"] = xyz.size();
}

/// The filtered advancing front through the points of front_points().
void front(const std::vector<Eigen::Vector3d>& xyz, const std::vector<Eigen::Vector3d>& normals,
           double spacing, const ReconstructionOptions& o, Mesh& mesh, Report& r) {
    const double max_edge = o.front_max_edge * spacing;
    const FrontPriority priority{&xyz, &normals, max_edge * max_edge,
                                 std::cos(o.front_max_normal_angle_deg * M_PI / 180.0),
                                 std::cos(o.front_max_facet_angle_deg * M_PI / 180.0)};
    Stopwatch af_watch;
    advancing_front(xyz, normals, &priority, o, mesh);
    r["front_time_s"] = af_watch.seconds();
}

/// The points an interpolating method ("front", "advancing-front") goes through, with their
/// normals; none for "poisson". For the front, smoothed and thinned (front_points(), at the
/// spacing `used_spacing`; its steps reported in `steps`).
void surface_points(const std::vector<Pwn>& pwn, double used_spacing,
                    const ReconstructionOptions& options, std::vector<Eigen::Vector3d>& xyz,
                    std::vector<Eigen::Vector3d>& normals, Report& steps) {
    if (options.method == "poisson") return;
    xyz.reserve(pwn.size());
    normals.reserve(pwn.size());
    for (const Pwn& p : pwn) {
        xyz.push_back(to_eigen(p.first));
        normals.push_back(to_eigen(p.second));
    }
    if (options.method == "front") front_points(xyz, normals, used_spacing, options, steps);
}

/// The surface by options.method: Screened Poisson ("poisson", through `pwn`, at
/// average_spacing), the filtered advancing front ("front", through the points `xyz` of
/// surface_points(), at used_spacing) or CGAL's plain advancing front (through `xyz`).
void surface_from_points(const std::vector<Pwn>& pwn, double average_spacing, double used_spacing,
                         const std::vector<Eigen::Vector3d>& xyz,
                         const std::vector<Eigen::Vector3d>& normals,
                         const ReconstructionOptions& options, Mesh& mesh, Report& steps) {
    if (options.method == "poisson")
        poisson(pwn, average_spacing, options, mesh);
    else if (options.method == "front")
        front(xyz, normals, used_spacing, options, mesh, steps);
    else
        advancing_front(xyz, normals, nullptr, options, mesh);
}

/// The space the sensors saw empty (holes::FreeSpace) from the cloud's measured points (not
/// the fill's synthetic ones), for the watertight closure's carving.
holes::FreeSpace measured_free_space(const PointCloud& cloud,
                                     const std::vector<holes::SensorView>& sensors,
                                     double spacing) {
    std::vector<Eigen::Vector3d> measured;
    const auto synthetic = cloud.flag(prop::kSynthetic);
    for (auto idx : cloud.points)
        if (!synthetic || !(*synthetic)[idx]) measured.push_back(to_eigen(cloud.points.point(idx)));
    holes::FreeSpaceOptions evidence;
    evidence.background_window = 3;
    return holes::FreeSpace(measured, sensors, spacing, evidence);
}

/// The oriented points the surface goes through: the cloud within the point budget
/// (bounded()), their spacing, the points with a direction, and CGAL's average spacing (6
/// neighbours), which Screened Poisson takes.
struct SurfaceInput {
    double voxel = 0.0;  ///< the budget's voxel; 0 when the cloud fits
    double used_spacing = 0.0;
    double average_spacing = 0.0;
    std::vector<Pwn> pwn;
};

SurfaceInput surface_input(const PointCloud& cloud, const ReconstructionOptions& options,
                           double spacing, const Progress& progress) {
    SurfaceInput in;
    const PointCloud used = internal::bounded(cloud, options.max_points, spacing, in.voxel);
    // The front works on the down-sampled points: its radii scale with their spacing (a dense
    // turn of 50 overlapping frames has ŝ 0.6 mm, its 60000-point voxel grid 5 mm).
    in.used_spacing =
        in.voxel > 0 ? std::max(spacing, sampling::robust_spacing(used.points)) : spacing;
    in.pwn.reserve(used.size());
    for (auto idx : used.points) {
        const Eigen::Vector3d n = to_eigen(used.points.normal(idx));
        if (n.squaredNorm() < 1e-24) continue;  // no direction: useless to Poisson
        in.pwn.emplace_back(used.points.point(idx), to_vector(n.normalized()));
    }
    RGBD_CHECK(in.pwn.size() >= 100, "reconstruction: " + view_name(cloud) +
                                         " has fewer than 100 points with a non-zero normal");
    if (!report_progress(progress, 0.05)) throw AlgorithmError("reconstruction: cancelled");
    in.average_spacing = CGAL::compute_average_spacing<CGAL::Parallel_if_available_tag>(
        in.pwn, 6, CGAL::parameters::point_map(PointOf()));
    return in;
}

/// The surface's clean-up before the closure: isolated vertices and small components dropped,
/// then (options.clean, not for Poisson) folds and spikes removed.
void clean_surface(Mesh& mesh, const ReconstructionOptions& options, const std::string& name,
                   Report& steps) {
    PMP::remove_isolated_vertices(mesh);
    mesh.collect_garbage();
    RGBD_CHECK_AS(AlgorithmError, mesh.number_of_faces() > 0,
                  "reconstruction: " + name + ": " + options.method + " produced no triangles");
    steps["components_dropped"] =
        internal::drop_small_components(mesh, options.min_component_fraction);
    if (options.clean && options.method != "poisson")
        steps["folds"] =
            internal::remove_folds_and_spikes(mesh, options.fold_angle_deg, options.spike_angle_deg,
                                              3, options.min_component_fraction);
}

/// The watertight closure (internal::close_holes), checked against the free space when there
/// is some; the faces it adds go to `added`.
Report close_surface(Mesh& mesh, const ReconstructionOptions& options,
                     const std::optional<holes::FreeSpace>& free,
                     std::vector<Mesh::Face_index>& added) {
    internal::SeenEmpty seen_empty;
    if (free) {
        seen_empty = [&free, votes = options.carve_votes](const Eigen::Vector3d& p,
                                                          const Eigen::Vector3d& n) {
            return free->count_seen_empty(p, n) >= votes;
        };
    }
    return internal::close_holes(mesh, options.up, options.fair_max_edges, &added, options.ground,
                                 options.ground_margin_m, seen_empty, options.seen_through_max,
                                 options.carve_steps);
}

}  // namespace

Mesh reconstruct_surface(const PointCloud& cloud, const ReconstructionOptions& options,
                         Report* report, const Progress& progress) {
    options.check();
    Stopwatch watch;
    const ScopedDefaultRandom seeded(0);
    RGBD_CHECK(cloud.size() >= 100, "reconstruction: " + view_name(cloud) + " has " +
                                        std::to_string(cloud.size()) +
                                        " points; at least 100 are needed");
    RGBD_CHECK(cloud.points.has_normal_map(),
               "reconstruction: " + view_name(cloud) +
                   " has no normals; estimate oriented normals first (rgbd::normals)");
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        const Eigen::Vector3d n = to_eigen(cloud.points.normal(idx));
        RGBD_CHECK(p.allFinite() && n.allFinite(),
                   "reconstruction: " + view_name(cloud) + " has a non-finite point or normal");
    }
    const double spacing = sampling::robust_spacing(cloud.points);
    RGBD_CHECK(spacing > 0, "reconstruction: " + view_name(cloud) + " has zero point spacing");

    // This thread's steps are isolated from the tasks below: waiting inside a parallel loop, it
    // does not pick up a task and leave the sequential surface step waiting for it. The tasks
    // are waited for outside the isolation (with one thread, only this one can run them).
    SurfaceInput in;
    std::vector<Eigen::Vector3d> xyz, normals;
    Mesh mesh;
    Report steps = Report::object();
    tbb::this_task_arena::isolate([&] {
        in = surface_input(cloud, options, spacing, progress);
        surface_points(in.pwn, in.used_spacing, options, xyz, normals, steps);
    });
    // Work that does not depend on the mesh runs in tasks beside the surface step, which is
    // sequential (the advancing front, Poisson's solve) and stays on this thread (its CGAL
    // random generator is this thread's, seeded above): the space the sensors saw empty, from
    // the measured input points, for the watertight closure (unused when the front closes the
    // surface by itself); the colour sources and the colours of the points the front goes
    // through (its vertices); the caller's options.beside_surface. The closure waits for the
    // first; the last two run in an arena of low priority, which a thread joins only when the
    // free-space maps leave it nothing to do: waiting for the maps after the front, this thread
    // helps build them instead of starting the colours and pictures (a 50-view sequence's maps
    // take 1.75 s of one core, twice the front's time), and the colours and pictures run while
    // the closure and its remeshing, which are sequential, take this thread.
    std::optional<holes::FreeSpace> free;
    tbb::task_group evidence_task;
    if (options.watertight && !options.sensors.empty())
        evidence_task.run(
            [&] { free.emplace(measured_free_space(cloud, options.sensors, spacing)); });
    const WaitAtExit wait_for_evidence{&evidence_task};
    internal::ColourSources colour_sources;
    internal::KnownColours known_colours;
    bool colored = false;
    double colour_prepare_time = 0.0;
    tbb::task_arena beside(tbb::task_arena::automatic, 1, tbb::task_arena::priority::low);
    tbb::task_group colour_task, caller_task;
    beside.execute([&] {
        colour_task.run([&] {
            Stopwatch prepare_watch;
            colored = internal::prepare_colours(cloud, colour_sources);
            if (colored)
                known_colours = internal::colour_points(xyz, colour_sources, options, spacing);
            colour_prepare_time = prepare_watch.seconds();
        });
        if (options.beside_surface) caller_task.run(options.beside_surface);
    });
    const WaitAtExit wait_beside{{&colour_task, &caller_task}, &beside};
    tbb::this_task_arena::isolate([&] {
        surface_from_points(in.pwn, in.average_spacing, in.used_spacing, xyz, normals, options,
                            mesh, steps);
        if (!report_progress(progress, 0.7)) throw AlgorithmError("reconstruction: cancelled");
        clean_surface(mesh, options, view_name(cloud), steps);
    });
    std::vector<Mesh::Face_index> added;
    if (options.watertight && !CGAL::is_closed(mesh)) {
        evidence_task.wait();  // the free-space maps, built beside the front
        tbb::this_task_arena::isolate(
            [&] { steps["holes"] = close_surface(mesh, options, free, added); });
    } else {
        // Closed components the front closed by itself (or every component when the closure
        // is not asked for) face outward too: close_holes orients what it closed.
        steps["components_reversed"] = internal::orient_outward(mesh);
    }
    tbb::this_task_arena::isolate([&] {
        if (options.clean && options.method != "poisson") {
            const bool closed_holes = !added.empty();
            // `added` follows the remeshing (its new faces count as closure).
            steps["regularize"] = internal::regularize_faces(mesh, added);
            if (closed_holes) steps["folded_patches"] = repair_folded_patches(mesh, added);
        }
        if (!report_progress(progress, 0.8)) throw AlgorithmError("reconstruction: cancelled");
        if (options.target_faces > 0)
            steps["simplification"] = internal::simplify_to_faces(mesh, options.target_faces);
        if (options.repair_self_intersections)
            steps["self_intersections"] = repair_self_intersections(mesh);
        if (!report_progress(progress, 0.9)) throw AlgorithmError("reconstruction: cancelled");
    });
    const double mesh_time = watch.seconds();
    beside.execute([&] {
        colour_task.wait();
        caller_task.wait();
    });
    evidence_task.wait();
    Stopwatch color_watch;
    if (colored) internal::colorize(mesh, colour_sources, options, spacing, &known_colours);
    report_progress(progress, 1.0);

    if (report) {
        Report& r = *report;
        r["method"] = options.method;
        r["points_in"] = cloud.size();
        r["points_used"] = in.pwn.size();
        r["voxel_m"] = in.voxel;
        r["spacing_m"] = spacing;
        r["used_spacing_m"] = in.used_spacing;
        r["average_spacing_m"] = in.average_spacing;
        r["vertices"] = mesh.number_of_vertices();
        r["faces"] = mesh.number_of_faces();
        std::size_t border_edges = 0;
        for (auto h : mesh.halfedges())
            if (mesh.is_border(h)) ++border_edges;
        r["border_edges"] = border_edges;
        r["closed"] = CGAL::is_closed(mesh);
        r["watertight_requested"] = options.watertight;
        for (auto it = steps.begin(); it != steps.end(); ++it) r[it.key()] = it.value();
        r["colored"] = colored;
        r["mesh_time_s"] = mesh_time;
        r["color_time_s"] = colour_prepare_time + color_watch.seconds();
        r["time_s"] = watch.seconds();
    }
    return mesh;
}

}  // namespace rgbd::reconstruction
