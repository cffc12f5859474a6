#include "algorithms/reconstruction/reconstruct_surface.hpp"

#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Random.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/compute_average_spacing.h>
#include <CGAL/property_map.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/holes/free_space.hpp"
#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/poisson_solver.hpp"
#include "algorithms/reconstruction/advancing_front.hpp"
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
    const internal::FrontFilter filter{o.front_max_edge * spacing, o.front_max_normal_angle_deg,
                                       o.front_max_facet_angle_deg};
    Stopwatch af_watch;
    internal::advancing_front(xyz, normals, &filter, o.af_radius_ratio_bound, o.af_beta, mesh);
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
        internal::advancing_front(xyz, normals, nullptr, options.af_radius_ratio_bound,
                                  options.af_beta, mesh);
}

/// The space the sensors saw empty (holes::FreeSpace) from the cloud's measured points (not
/// the fill's synthetic ones) and `more` of the sensors' measurements around them
/// (ReconstructionOptions::evidence_points), for the watertight closure's carving.
holes::FreeSpace measured_free_space(const PointCloud& cloud,
                                     const std::vector<holes::SensorView>& sensors,
                                     const std::vector<Eigen::Vector3d>& more, double spacing) {
    std::vector<Eigen::Vector3d> measured;
    const auto synthetic = cloud.flag(prop::kSynthetic);
    for (auto idx : cloud.points)
        if (!synthetic || !(*synthetic)[idx]) measured.push_back(to_eigen(cloud.points.point(idx)));
    holes::FreeSpaceOptions evidence;
    evidence.background_window = 3;
    return holes::FreeSpace(measured, sensors, spacing, evidence, more);
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
        evidence_task.run([&] {
            free.emplace(
                measured_free_space(cloud, options.sensors, options.evidence_points, spacing));
        });
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
