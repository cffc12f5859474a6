#include "algorithms/reconstruction/mesh_finishing.hpp"

#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/fair.h>
#include <CGAL/Polygon_mesh_processing/refine.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Polygon_mesh_processing/repair_degeneracies.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_normal_change_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/boost/graph/Euler_operations.h>
#include <CGAL/boost/graph/helpers.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <vector>

#include "algorithms/reconstruction/closure_base.hpp"
#include "algorithms/reconstruction/closure_carving.hpp"
#include "toolkit/order_statistics.hpp"
#include "toolkit/report.hpp"

namespace rgbd::reconstruction::internal {

namespace PMP = CGAL::Polygon_mesh_processing;
namespace SMS = CGAL::Surface_mesh_simplification;

std::size_t drop_small_components(Mesh& mesh, double min_fraction) {
    if (mesh.number_of_faces() == 0 || min_fraction <= 0) return 0;
    auto fcc = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:rgbd_cc", 0).first;
    const std::size_t count = PMP::connected_components(mesh, fcc);
    std::vector<std::size_t> sizes(count, 0);
    for (auto f : mesh.faces()) ++sizes[fcc[f]];
    mesh.remove_property_map(fcc);
    const std::size_t largest = *std::max_element(sizes.begin(), sizes.end());
    const auto threshold = static_cast<std::size_t>(std::ceil(min_fraction * largest));
    const std::size_t removed = PMP::keep_large_connected_components(mesh, threshold);
    PMP::remove_isolated_vertices(mesh);
    mesh.collect_garbage();
    return removed;
}

namespace {

/// Holes with more corners are triangulated in a 3D Delaunay search space (see close_holes).
constexpr std::size_t kCubicMaxEdges = 300;

using Halfedge = Mesh::Halfedge_index;

std::size_t loop_length(const Mesh& mesh, Halfedge h) {
    std::size_t n = 0;
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh)) {
        (void)x;
        ++n;
    }
    return n;
}

/// Ball around a boundary loop: the centroid of its vertices and the largest distance to one.
struct RimBall {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    double radius = 0;
};

RimBall rim_ball(const Mesh& mesh, Halfedge h) {
    RimBall ball;
    std::size_t n = 0;
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh)) {
        ball.centre += to_eigen(mesh.point(mesh.target(x)));
        ++n;
    }
    ball.centre /= static_cast<double>(n);
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh))
        ball.radius =
            std::max(ball.radius, (to_eigen(mesh.point(mesh.target(x))) - ball.centre).norm());
    return ball;
}

/// How far from its rim's centroid a faired patch may reach, in rim radii. A faired patch is a
/// membrane over its rim: on the 16 objects of the variety set (1,499 faired holes, seed 1) no
/// new vertex lay farther than 1.02 rim radii from the centroid (a dome reaches 1), but once
/// CGAL's sparse solve of a near-singular system reported success with a vertex 17 radii
/// (1.4 m) away: the lion head's closed mesh grew a trail of faces through empty space.
constexpr double kFairMaxReach = 2.0;

/// What guarded_fair did.
enum class FairOutcome { kTangent, kHarmonic, kUnfaired };

/// PMP::fair of the patch's new `vertices` with tangent (C1) continuity, kept when the solve
/// succeeds and leaves every vertex within kFairMaxReach rim radii of `ball`; otherwise the
/// positions are restored and a harmonic (C0) fairing, better conditioned, is tried alike;
/// otherwise the patch keeps its refined, unfaired positions.
FairOutcome guarded_fair(Mesh& mesh, const std::vector<Mesh::Vertex_index>& vertices,
                         const RimBall& ball) {
    std::vector<Point_3> before;
    before.reserve(vertices.size());
    for (auto v : vertices) before.push_back(mesh.point(v));
    const double reach = kFairMaxReach * ball.radius;
    const auto attempt = [&](unsigned continuity) {
        const bool solved =
            PMP::fair(mesh, vertices, CGAL::parameters::fairing_continuity(continuity));
        bool within = solved;
        for (auto v : vertices)
            within = within && (to_eigen(mesh.point(v)) - ball.centre).norm() <= reach;
        if (within) return true;
        for (std::size_t i = 0; i < vertices.size(); ++i) mesh.point(vertices[i]) = before[i];
        return false;
    };
    if (attempt(1)) return FairOutcome::kTangent;
    if (attempt(0)) return FairOutcome::kHarmonic;
    return FairOutcome::kUnfaired;
}

/// Closes the loop of border halfedge h by one polygon, then a fan around its centroid, then
/// refines and fairs the fan (a smooth patch instead of a cone; guarded_fair).
void fan_fill(Mesh& mesh, Halfedge h) {
    const RimBall ball = rim_ball(mesh, h);
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    for (Halfedge x : CGAL::halfedges_around_face(h, mesh)) {
        c += to_eigen(mesh.point(mesh.target(x)));
        ++n;
    }
    c /= static_cast<double>(n);
    CGAL::Euler::fill_hole(h, mesh);
    const Halfedge center = CGAL::Euler::add_center_vertex(h, mesh);
    const Mesh::Vertex_index apex = mesh.target(center);
    mesh.point(apex) = to_point(c);
    std::vector<Mesh::Face_index> fan;
    for (auto f : CGAL::faces_around_target(center, mesh))
        if (f != Mesh::null_face()) fan.push_back(f);
    std::vector<Mesh::Face_index> new_faces;
    std::vector<Mesh::Vertex_index> new_vertices{apex};
    PMP::refine(mesh, fan, std::back_inserter(new_faces), std::back_inserter(new_vertices),
                CGAL::parameters::density_control_factor(std::sqrt(2.0)));
    guarded_fair(mesh, new_vertices, ball);
}

/// Whether more than `max_share` of a patch's face centres (outward face normals) were seen
/// empty by a sensor; patches of fewer than 20 faces never are (small holes: the noise of the
/// evidence).
bool seen_through(const Mesh& mesh, const std::vector<Mesh::Face_index>& faces,
                  const SeenEmpty& seen_empty, double max_share) {
    if (faces.size() < 20) return false;
    std::size_t empty = 0;
    for (auto f : faces) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
            c += to_eigen(mesh.point(v));
        c /= 3.0;
        const Eigen::Vector3d n = to_eigen(PMP::compute_face_normal(f, mesh));
        empty += seen_empty(c, n);
    }
    return static_cast<double>(empty) > max_share * static_cast<double>(faces.size());
}

/// Rim edges that the stages after the extraction's ground cut (distance and density outlier
/// removal, the mesher's thinning and its boundary) can wear off a cut that stood on the ground,
/// on top of the cut's margin. Measured on the variety set in a room (floor, walls, clutter, a
/// person; validation/results/2026-12-07-bases-on-the-floor.md): the rims of subjects standing on
/// the floor lay 0.5-3.5 rim edges above the cut's margin.
constexpr double kWornEdges = 3.0;

/// The median length of the edges of the loops of `borders` flagged in `flags` (metres; 0 when
/// none).
double median_edge_length(const Mesh& mesh, const std::vector<Halfedge>& borders,
                          const std::vector<char>& flags) {
    std::vector<double> lengths;
    for (std::size_t i = 0; i < borders.size(); ++i) {
        if (!flags[i]) continue;
        for (Halfedge x : CGAL::halfedges_around_face(borders[i], mesh))
            lengths.push_back(
                (to_eigen(mesh.point(mesh.target(x))) - to_eigen(mesh.point(mesh.source(x))))
                    .norm());
    }
    return lengths.empty() ? 0.0 : rank_quantile(lengths, 0.5);
}

/// The sides of a cut's loop `h` carried down to the base (extrude_to_support): to the shared
/// `support` plane, or, off the ground, to the loop's own rim when the shared plane lies lower
/// (counted in `own_rim`); on the ground, carved out of the space the sensors saw empty
/// (carve_walls, the feet moved counted in `feet_moved`). Returns the new bottom loop.
Halfedge cut_walls(Mesh& mesh, Halfedge h, const SupportPlane& support, const Eigen::Vector3d& up,
                   bool on_ground, const SeenEmpty& seen_empty, int carve_steps,
                   std::size_t& own_rim, std::size_t& feet_moved) {
    // No skirt: without the ground, a loop's walls never go further down than its own rim's
    // deep quintile (plus its noise); a plane pooled with lower loops (an island of noise below,
    // a ragged part) would carry them through space the sensors saw empty.
    SupportPlane own = support;
    if (!on_ground) {
        const std::vector<Eigen::Vector3d> points = loop_points(mesh, h);
        const SupportPlane mine = support_plane(points, up);
        const LoopPlane plane = fit_loop_plane(points);
        const double below = (support.point - mine.point).dot(mine.down);
        if (below > std::max(0.002, 3.0 * plane.robust_rms)) {
            own = mine;
            ++own_rim;
        }
    }
    // On the ground: the walls carved out of the space the sensors saw empty (the floor seen
    // through a skirt round a rounded bottom).
    std::vector<std::pair<Mesh::Vertex_index, Mesh::Vertex_index>> walls;
    h = extrude_to_support(mesh, h, own, up, on_ground ? &walls : nullptr);
    if (on_ground && seen_empty && carve_steps > 0)
        feet_moved += carve_walls(mesh, walls, own.point, own.down, seen_empty, carve_steps);
    return h;
}

/// Where the base of the cut the object stood on goes (docs/algorithms.md §14). `support` is
/// the rim's own plane at its deep quintile (support_loops); `rim` its vertices, flagged in
/// `on_support` among `borders`. With a ground that the rim reaches (its deep quintile within the
/// cut's margin plus 3 robust RMS of the rim's plane, at least 1 cm, plus kWornEdges rim edges),
/// `support` is moved down along `up` until its lowest point over the rim touches the ground.
/// Report: kind ("ground" or "rim"), and with a ground rim_above_ground_m, reach_m and
/// rim_tilt_deg.
Report place_base(const Mesh& mesh, const std::vector<Halfedge>& borders,
                  const std::vector<char>& on_support, const std::vector<Eigen::Vector3d>& rim,
                  const Eigen::Vector3d& up, const std::optional<Eigen::Vector4d>& ground,
                  double ground_margin_m, SupportPlane& support) {
    Report base;
    base["kind"] = "rim";
    if (!ground || !ground->head<3>().allFinite() || !std::isfinite((*ground)(3))) return base;
    const Eigen::Vector3d n = ground->head<3>().normalized();
    const double d = (*ground)(3) / ground->head<3>().norm();
    // The rim's deep quintile above the ground, and its spread.
    std::vector<double> heights;
    for (const auto& p : rim) heights.push_back(n.dot(p) + d);
    const double deep = rank_quantile(heights, 0.2);
    const LoopPlane plane = fit_loop_plane(rim);
    // What lies between the rim and the ground went in the extraction's cut (its margin) or was
    // worn off the cut's edge by the cleaning and meshing stages that follow, each working at
    // about the point spacing: the rim's edge length measures it.
    const double edge = median_edge_length(mesh, borders, on_support);
    const double reach =
        std::max(0.01, ground_margin_m + 3.0 * plane.robust_rms) + kWornEdges * edge;
    base["rim_above_ground_m"] = deep;
    base["reach_m"] = reach;
    base["rim_tilt_deg"] =
        std::acos(std::min(1.0, std::abs(plane.robust_normal.dot(n)))) * 180.0 / M_PI;
    if (deep > reach) return base;
    // The object rests on the ground on its cut: the base keeps the cut's own plane and goes down
    // until its lowest point over the rim touches the ground. A cut parallel to the ground lies
    // on it; an oblique cut (a neck cut at a slant, feet of different heights) touches it at one
    // side, where a base on the ground plane put a wedge under it.
    double lowest = std::numeric_limits<double>::infinity();
    for (const auto& p : rim) {
        // p moved along up onto the cut's plane, its height above the ground
        const double t = (p - support.point).dot(support.down) / up.dot(support.down);
        lowest = std::min(lowest, n.dot(p - t * up) + d);
    }
    support.point -= lowest / n.dot(up) * up;
    base["kind"] = "ground";
    return base;
}

}  // namespace

Report close_holes(Mesh& mesh, const std::optional<Eigen::Vector3d>& up_in,
                   std::size_t fair_max_edges, std::vector<Mesh::Face_index>* added,
                   const std::optional<Eigen::Vector4d>& ground, double ground_margin_m,
                   const SeenEmpty& seen_empty, double seen_through_max, int carve_steps) {
    Stopwatch watch;
    // Faces present before the fill are marked; without garbage, new faces are never recycled
    // ones and start unmarked.
    mesh.collect_garbage();
    auto old_face = mesh.add_property_map<Mesh::Face_index, char>("f:rgbd_old", 0).first;
    for (auto f : mesh.faces()) old_face[f] = 1;
    std::optional<Eigen::Vector3d> up;
    if (up_in && up_in->allFinite() && up_in->norm() > 0) up = up_in->normalized();
    double low = std::numeric_limits<double>::infinity(), high = -low;
    if (up)
        for (auto v : mesh.vertices()) {
            const double height = to_eigen(mesh.point(v)).dot(*up);
            low = std::min(low, height);
            high = std::max(high, height);
        }
    std::vector<Halfedge> borders;
    PMP::extract_boundary_cycles(mesh, std::back_inserter(borders));
    std::size_t faired = 0, refined = 0, flat = 0, fans = 0, largest = 0, own_rim = 0,
                left_open = 0;  // patches the sensors saw through
    // Faired patches whose tangent fairing was refused (guarded_fair): harmonic, or unfaired.
    std::size_t fair_harmonic = 0, fair_unfaired = 0;
    struct Patch {
        std::vector<Mesh::Face_index> faces;
        std::vector<Mesh::Vertex_index> vertices;
    };
    // Faired or refined patches, and bases not on the ground: carved once all are closed.
    std::vector<Patch> patches;
    std::size_t carvable_cuts = 0, feet_moved = 0;
    const std::size_t faces_before = mesh.number_of_faces();
    SupportPlane support;
    std::vector<Eigen::Vector3d> rim;
    const std::vector<char> on_support =
        up ? support_loops(mesh, borders, *up, low, high, support, &rim)
           : std::vector<char>(borders.size(), 0);
    Report base;
    if (up && !rim.empty())
        base = place_base(mesh, borders, on_support, rim, *up, ground, ground_margin_m, support);
    const bool on_ground = base.is_object() && base.value("kind", std::string()) == "ground";
    for (std::size_t loop = 0; loop < borders.size(); ++loop) {
        Halfedge h = borders[loop];
        if (!mesh.is_border(h)) continue;  // closed by an earlier fill
        const std::size_t edges = loop_length(mesh, h);
        largest = std::max(largest, edges);
        std::vector<Mesh::Face_index> faces;
        std::vector<Mesh::Vertex_index> vertices;
        // A hole that projects onto its plane is triangulated by a 2D constrained Delaunay
        // triangulation; else by Liepa's dynamic programme over all triangulations (cubic in
        // the corners, 0.4 s for 200). The 3D Delaunay search space is faster but picks its
        // triangles by comparing cell addresses: the mesh depended on the heap's layout (the
        // length of the input file's name changed it), so it is used only past the cubic
        // algorithm's reach.
        const bool large = edges > kCubicMaxEdges;
        const auto np = CGAL::parameters::use_delaunay_triangulation(large)
                            .use_2d_constrained_delaunay_triangulation(true)
                            .do_not_use_cubic_algorithm(large);
        bool ok = false;
        const bool cut =
            up ? on_support[loop] != 0 : is_crease_cut(mesh, h, fit_loop_plane(mesh, h));
        if (cut) {
            // The object stood on its cut: the sides go down to it (the sensors rarely see
            // their last millimetres), then the base is flat.
            if (up)
                h = cut_walls(mesh, h, support, *up, on_ground, seen_empty, carve_steps, own_rim,
                              feet_moved);
            PMP::triangulate_and_refine_hole(mesh, h, std::back_inserter(faces),
                                             std::back_inserter(vertices), np);
            ok = !faces.empty();
            if (ok) ++flat;
            // A base at the rim's own height (not on the detected ground) is a guess like a
            // faired patch: carved alike where the sensors saw through it (a rounded underside,
            // the bear's). A base on the ground rests on measured support: it stays.
            if (ok && !on_ground) {
                patches.push_back({std::move(faces), std::move(vertices)});
                ++carvable_cuts;
            }
        } else {
            if (edges <= fair_max_edges) {
                // CGAL's triangulate_refine_and_fair_hole, with the fairing guarded.
                const RimBall ball = rim_ball(mesh, h);
                PMP::triangulate_and_refine_hole(mesh, h, std::back_inserter(faces),
                                                 std::back_inserter(vertices), np);
                ok = !faces.empty();
                if (ok) {
                    ++faired;
                    const FairOutcome outcome = guarded_fair(mesh, vertices, ball);
                    fair_harmonic += outcome == FairOutcome::kHarmonic;
                    fair_unfaired += outcome == FairOutcome::kUnfaired;
                }
            } else {
                PMP::triangulate_and_refine_hole(mesh, h, std::back_inserter(faces),
                                                 std::back_inserter(vertices), np);
                ok = !faces.empty();
                if (ok) ++refined;
            }
            if (ok) patches.push_back({std::move(faces), std::move(vertices)});
        }
        if (!ok && mesh.is_border(h)) {
            fan_fill(mesh, h);
            ++fans;
        }
    }
    // Once closed, each component bounds a volume: oriented outward (a front can close
    // inside out), then the faired patches carved back out of the space the sensors saw empty;
    // the evidence left is reported: patches the sensors still see through. (Removing such
    // patches left holes in simple closed objects, an egg and the bunny: the evidence is too
    // noisy at patch scale to open a watertight mesh on.)
    const std::size_t reversed = orient_outward(mesh);
    std::size_t carved = 0, carved_vertices = 0;
    if (seen_empty)
        for (const Patch& patch : patches) {
            if (carve_steps > 0) {
                const std::size_t n =
                    carve_patch(mesh, patch.faces, patch.vertices, seen_empty, carve_steps);
                carved_vertices += n;
                carved += n > 0;
            }
            if (seen_through(mesh, patch.faces, seen_empty, seen_through_max)) ++left_open;
        }
    if (added)
        for (auto f : mesh.faces())
            if (!old_face[f]) added->push_back(f);
    mesh.remove_property_map(old_face);
    Report r;
    r["holes"] = borders.size();
    r["faired"] = faired;
    r["fair_harmonic"] = fair_harmonic;
    r["fair_unfaired"] = fair_unfaired;
    r["refined"] = refined;
    r["flat_cuts"] = flat;
    r["flat_cuts_carvable"] = carvable_cuts;
    r["fans"] = fans;
    r["seen_through"] = left_open;
    r["carved_patches"] = carved;
    r["carved_vertices"] = carved_vertices;
    r["carved_wall_feet"] = feet_moved;
    r["components_reversed"] = reversed;
    r["largest_hole_edges"] = largest;
    if (up)
        r["up"] = {(*up)(0), (*up)(1), (*up)(2)};
    else
        r["up"] = nullptr;
    if (!base.is_null()) {
        base["own_rim_loops"] = own_rim;
        r["base"] = base;
    }
    r["faces_added"] = mesh.number_of_faces() - faces_before;
    r["time_s"] = watch.seconds();
    return r;
}

namespace {

Eigen::Vector3d face_unit_normal(const Mesh& mesh, Mesh::Face_index f) {
    const Halfedge h = mesh.halfedge(f);
    const Eigen::Vector3d a = to_eigen(mesh.point(mesh.source(h)));
    const Eigen::Vector3d b = to_eigen(mesh.point(mesh.target(h)));
    const Eigen::Vector3d c = to_eigen(mesh.point(mesh.target(mesh.next(h))));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double len = n.norm();
    return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

/// Smallest interior angle of face f, degrees.
double min_angle_deg(const Mesh& mesh, Mesh::Face_index f) {
    double smallest = 180.0;
    for (Halfedge h : CGAL::halfedges_around_face(mesh.halfedge(f), mesh)) {
        const Eigen::Vector3d p = to_eigen(mesh.point(mesh.target(h)));
        const Eigen::Vector3d u = to_eigen(mesh.point(mesh.source(h))) - p;
        const Eigen::Vector3d w = to_eigen(mesh.point(mesh.target(mesh.next(h)))) - p;
        const double angle = std::atan2(u.cross(w).norm(), u.dot(w)) * 180.0 / M_PI;
        smallest = std::min(smallest, angle);
    }
    return smallest;
}

}  // namespace

Report remove_folds_and_spikes(Mesh& mesh, double max_fold_deg, double spike_angle_deg, int rounds,
                               double min_component_fraction) {
    const double cos_fold = std::cos(max_fold_deg * M_PI / 180.0);
    std::size_t folds = 0, spikes = 0;
    for (int round = 0; round < rounds; ++round) {
        auto cut = mesh.add_property_map<Mesh::Face_index, char>("f:rgbd_cut", 0).first;
        auto normal = mesh.add_property_map<Mesh::Face_index, Eigen::Vector3d>(
                              "f:rgbd_n", Eigen::Vector3d::Zero())
                          .first;
        for (auto f : mesh.faces()) normal[f] = face_unit_normal(mesh, f);
        std::vector<Mesh::Face_index> doomed;
        auto doom = [&](Mesh::Face_index f) {
            if (!cut[f]) cut[f] = 1, doomed.push_back(f);
        };
        std::size_t round_folds = 0;
        for (auto e : mesh.edges()) {
            const Halfedge h = mesh.halfedge(e);
            const auto f = mesh.face(h), g = mesh.face(mesh.opposite(h));
            if (f == Mesh::null_face() || g == Mesh::null_face()) continue;
            if (normal[f].dot(normal[g]) < cos_fold) {
                const std::size_t before = doomed.size();
                doom(f);
                doom(g);
                round_folds += doomed.size() - before;
            }
        }
        std::size_t round_spikes = 0;
        for (auto f : mesh.faces()) {
            if (cut[f]) continue;
            int border = 0;
            for (Halfedge h : CGAL::halfedges_around_face(mesh.halfedge(f), mesh))
                border += mesh.is_border(mesh.opposite(h));
            if (border >= 2 || (border == 1 && min_angle_deg(mesh, f) < spike_angle_deg)) {
                doom(f);
                ++round_spikes;
            }
        }
        mesh.remove_property_map(normal);
        mesh.remove_property_map(cut);
        if (doomed.empty()) break;
        for (auto f : doomed) CGAL::Euler::remove_face(mesh.halfedge(f), mesh);
        folds += round_folds;
        spikes += round_spikes;
        PMP::duplicate_non_manifold_vertices(mesh);
        mesh.collect_garbage();
    }
    Report r;
    r["fold_faces"] = folds;
    r["spike_faces"] = spikes;
    r["components_dropped"] = drop_small_components(mesh, min_component_fraction);
    return r;
}

namespace {

/// regularize_faces() without the patch's tracking and the time.
Report regularize_patch(Mesh& mesh, const std::vector<Mesh::Face_index>& patch) {
    auto in_patch = mesh.add_property_map<Mesh::Face_index, char>("f:rgbd_patch", 0).first;
    for (auto f : patch) in_patch[f] = 1;
    // Target: the median edge of the faces outside the patch (the reconstruction's own).
    std::vector<double> lengths;
    for (auto e : mesh.edges()) {
        const Halfedge h = mesh.halfedge(e);
        const auto f = mesh.face(h), g = mesh.face(mesh.opposite(h));
        if ((f != Mesh::null_face() && !in_patch[f]) || (g != Mesh::null_face() && !in_patch[g]))
            lengths.push_back(std::sqrt(
                CGAL::squared_distance(mesh.point(mesh.source(h)), mesh.point(mesh.target(h)))));
    }
    if (lengths.empty())
        for (auto e : mesh.edges())
            lengths.push_back(
                std::sqrt(CGAL::squared_distance(mesh.point(mesh.source(mesh.halfedge(e))),
                                                 mesh.point(mesh.target(mesh.halfedge(e))))));
    const double target = lengths.empty() ? 0.0 : upper_median(lengths);
    // The patch and its one-ring (the faces sharing a vertex with it).
    std::vector<Mesh::Face_index> region(patch.begin(), patch.end());
    for (auto f : patch)
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
            for (auto g : CGAL::faces_around_target(mesh.halfedge(v), mesh))
                if (g != Mesh::null_face() && !in_patch[g]) in_patch[g] = 1, region.push_back(g);
    mesh.remove_property_map(in_patch);
    // No tangential relaxation: CGAL 5.5's dereferences a null halfedge on some patches
    // (CGAL issue 7345, a segfault on the Max Planck ring); splits, collapses and flips alone
    // already give well-shaped triangles.
    if (!region.empty() && target > 0)
        PMP::isotropic_remeshing(
            region, target, mesh,
            CGAL::parameters::number_of_iterations(3).number_of_relaxation_steps(0));
    std::size_t faces_before = mesh.number_of_faces();
    if (target > 0)
        PMP::experimental::remove_almost_degenerate_faces(mesh, std::cos(160.0 * M_PI / 180.0), 4.0,
                                                          target);
    PMP::remove_isolated_vertices(mesh);
    mesh.collect_garbage();
    Report r;
    r["remeshed_faces"] = region.size();
    r["target_edge_m"] = target;
    r["degenerate_removed"] =
        faces_before - std::min<std::size_t>(faces_before, mesh.number_of_faces());
    return r;
}

}  // namespace

void track_faces(Mesh& mesh, std::vector<Mesh::Face_index>& faces,
                 const std::function<void()>& edit) {
    auto tracked = mesh.add_property_map<Mesh::Face_index, char>("f:rgbd_tracked", 1).first;
    for (auto f : mesh.faces()) tracked[f] = 0;
    for (auto f : faces) tracked[f] = 1;
    edit();
    mesh.collect_garbage();
    faces.clear();
    for (auto f : mesh.faces())
        if (tracked[f]) faces.push_back(f);
    mesh.remove_property_map(tracked);
}

Report regularize_faces(Mesh& mesh, std::vector<Mesh::Face_index>& patch) {
    Stopwatch watch;
    Report r;
    track_faces(mesh, patch, [&] { r = regularize_patch(mesh, patch); });
    r["time_s"] = watch.seconds();
    return r;
}

namespace {

/// Stops the collapse once the mesh has at most `target` faces.
struct FaceBudget {
    const Mesh* mesh;
    std::size_t target;
    template <typename FT, typename Profile>
    bool operator()(const FT&, const Profile&, std::size_t, std::size_t) const {
        return mesh->number_of_faces() <= target;
    }
};

}  // namespace

Report simplify_to_faces(Mesh& mesh, std::size_t target_faces) {
    Stopwatch watch;
    Report r;
    r["faces_before"] = mesh.number_of_faces();
    std::size_t collapsed = 0;
    if (mesh.number_of_faces() > target_faces) {
        using Policies = SMS::GarlandHeckbert_plane_policies<Mesh, Kernel>;
        Policies policies(mesh);
        const SMS::Bounded_normal_change_placement<Policies::Get_placement> placement(
            policies.get_placement());
        collapsed = static_cast<std::size_t>(SMS::edge_collapse(
            mesh, FaceBudget{&mesh, target_faces},
            CGAL::parameters::get_cost(policies.get_cost()).get_placement(placement)));
        mesh.collect_garbage();
    }
    r["faces_after"] = mesh.number_of_faces();
    r["collapsed_edges"] = collapsed;
    r["time_s"] = watch.seconds();
    return r;
}

}  // namespace rgbd::reconstruction::internal
