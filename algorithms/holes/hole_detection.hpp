// Hole detection on point sets (docs/algorithms.md §9 and §10): the "3D gradient" (normals, tangent
// frames, surface variation, tangent-plane colour gradients), per-point boundary probabilities
// from the angle, half-disk and shape criteria of Bendels, Schnabel and Klein, "Detecting holes
// in point set surfaces" (WSCG 2006), as implemented in the public code huyaoyu/PointCloudUtils,
// their combination and coherence filter, boundary loops with a small / large class, and a
// sensor-visibility test telling occlusion holes (no sensor could see the region) from real
// openings (a sensor looked through the region and measured nothing there: the gap between an
// arm and the body).
// Peers: PCL BoundaryEstimation and Open3D t.geometry.PointCloud.compute_boundary_points (angle
// criterion with a hard 90-degree threshold; validation/quality/holes/measure_boundary.py).
// See also: algorithms/holes/hole_filling.hpp (§11), algorithms/normals/estimate_normals.hpp.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "toolkit/camera.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::prop {
// Properties written by rgbd-fill (PLY names; beside the core ones of toolkit/point_cloud.hpp).
inline constexpr const char* kBoundary = "boundary";  ///< uint8 flag, hole-rim point (§10)
/// float, combined boundary probability P of §10 step 6
inline constexpr const char* kBoundaryProbability = "boundary_probability";
/// uint8, mechanism that added a point (1-3: M1-M3 of §11, 4: M4 interpolation, 5: large hole
/// §12, 6: head top §13)
inline constexpr const char* kFillMechanism = "fill_mechanism";
}  // namespace rgbd::prop

namespace rgbd::internal {
class KdTree;
}

namespace rgbd::holes {

/// A merged surface sample set in one (world) frame: what §9-§11 work on.
struct SurfacePoints {
    std::vector<Eigen::Vector3d> position;
    std::vector<Eigen::Vector3d> normal;  ///< unit normals, or empty (estimated by §9)
    std::vector<Rgb> color;               ///< empty = no colour
    std::vector<int> view;                ///< index into `sensors` per point, or empty
    std::size_t size() const { return position.size(); }
};

/// A sensor that observed the surface: its centre (and optionally its depth camera), in the
/// frame of the SurfacePoints.
struct SensorView {
    Pose world_from_sensor = Pose::Identity();
    std::optional<PinholeIntrinsics> intrinsics;  ///< frustum test when known
};

/// Gathers views into SurfacePoints in the world frame (sensor-frame views are moved with their
/// pose; InputError without one, unless it is the only non-empty view: then it is taken as it
/// is, a plain point file). Normals are kept when every non-empty view has them, colours
/// when every non-empty view has them. `sensors` receives one entry per view that has a pose
/// (world-frame views without a pose get none; their points have view = -1). With
/// `measured_only`, points flagged synthetic (super-resolution, an earlier fill) are left out:
/// holes are where no sensor measured, and the robust spacing stays the sensors'.
SurfacePoints gather_views(const std::vector<const PointCloud*>& views,
                           std::vector<SensorView>* sensors, bool measured_only = false);

/// Thins `points` to at most `max_points` with a voxel grid (grid anchored at the bounding
/// box's minimum corner): each occupied voxel keeps the one input point nearest to its centre
/// (a regular sampling, about one edge apart), with that point's normal, colour and view, never an
/// average, so the visibility test still knows which sensor measured it. The voxel edge is searched
/// (a few passes over the points) so that the occupied voxels number between 70% and 100% of
/// `max_points`; `voxel_m` receives it (metres), or 0 when the points already fit (returned
/// unchanged). Output order: by voxel, deterministic for any thread count. Used by the fill
/// stage on merged sequences (50 overlapping frames of a person: 2.7 million points at 0.6 mm
/// spacing, where the mesher keeps 60,000): holes the mesh can show are still found.
SurfacePoints thin_points(const SurfacePoints& points, std::size_t max_points,
                          double* voxel_m = nullptr);

/// Symmetric neighbourhood graph in compressed rows: neighbours of i are
/// index[offset[i] .. offset[i+1]), the point itself excluded.
struct Neighbourhood {
    std::vector<std::uint32_t> offset;
    std::vector<std::uint32_t> index;
    std::size_t degree(std::size_t i) const { return offset[i + 1] - offset[i]; }
};

struct NeighbourhoodOptions {
    int k = 10;                  ///< nearest neighbours (point itself excluded)
    double radius_factor = 2.5;  ///< radius neighbours within this multiple of the spacing
    int max_neighbours = 64;     ///< cap of the kNN-or-radius set before symmetrisation
    bool symmetric = true;       ///< if q in N(p) then p in N(q) (§10 step 1)
    void check() const;
};

/// N(p) = kNN(k) union radius(radius_factor * spacing_m), capped, then made symmetric.
Neighbourhood build_neighbourhood(const std::vector<Eigen::Vector3d>& points, double spacing_m,
                                  const NeighbourhoodOptions& options);

/// §9: local differential quantities per point.
struct SurfaceGradient {
    std::vector<Eigen::Vector3d> normal;  ///< unit; given normals are kept
    std::vector<Eigen::Vector3d> e1, e2;  ///< tangent frame, (e1, e2, normal) right-handed
    std::vector<float> variation;         ///< surface variation l0 / (l0 + l1 + l2)
    /// Tangent-plane gradient of the intensity I = (R + G + B) / 3 (8-bit levels per metre);
    /// empty without colours.
    std::vector<Eigen::Vector3d> color_gradient;
};

struct GradientOptions {
    NeighbourhoodOptions neighbourhood{16, 2.5, 64, false};  ///< §9 step 1
    /// Estimate normals even when the points carry some.
    bool recompute_normals = false;
    void check() const;
};

/// Computes the §9 quantities. Estimated normals are oriented towards the sensor of the point's
/// view when known, else away from the centroid. TBB-parallel, same result for any thread count.
SurfaceGradient compute_surface_gradient(const SurfacePoints& points, double spacing_m,
                                         const std::vector<SensorView>& sensors,
                                         const GradientOptions& options);

/// What a boundary loop is, from the sensors' point of view.
enum class HoleKind {
    kUnknown,    ///< no sensor poses: nothing to tell
    kOcclusion,  ///< no sensor had a clear, front-facing view of the region: fill it
    kOpening,    ///< some sensor looked straight at the region and measured nothing: keep open
};
const char* to_string(HoleKind kind);

/// One connected rim of boundary points.
struct BoundaryLoop {
    std::vector<std::uint32_t> points;  ///< indices of its boundary points
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< normal of the rim's best plane
    double diameter_m = 0;                              ///< largest extent of the rim
    bool small = false;  ///< §10 step 10: fill locally (§11), else §12
    HoleKind kind = HoleKind::kUnknown;
    int seen_by = 0;  ///< sensors with a clear view of the region
};

struct BoundaryOptions {
    NeighbourhoodOptions neighbourhood;  ///< §10 step 1 (k 10, 2.5 spacing, symmetric)
    double spacing_m = 0;                ///< robust spacing; 0 = estimate (§0.2)
    double w_angle = 0.4, w_halfdisk = 0.4, w_shape = 0.2;  ///< §10 step 6
    double threshold = 0.5;  ///< boundary candidate if P >= threshold
    /// Ideal normalised eigenvalues (largest, middle) of a boundary neighbourhood about its
    /// centroid, calibrated on a jittered plane with holes for this neighbourhood (§10 step 5).
    double lambda_b0 = 0.70, lambda_b1 = 0.30;
    int coherence_passes = 1;  ///< §10 step 7 (0 = off)
    /// true: both gap-bounding neighbours must be candidates ([C], the third-party rule);
    /// false (default [M]): at least one. The strict rule drops real rim points where the gap
    /// is bounded by a second-row point: recall 0.94 -> 0.98 on the sampled bunny
    /// (validation/quality/holes/measure_boundary.py), no more false points (isolated
    /// candidates still go, and rims need min_loop_points).
    bool coherence_both = false;
    /// Hysteresis [M]: points of P >= this next to a loop join it (0 = off), up to
    /// hysteresis_rings graph rings away from its points. Measured on the sampled meshes of
    /// validation/quality/holes/measure_boundary.py (rim recall / false rate): off 0.88 / 0 on
    /// the shark (rim points at sharp hole corners see gaps of ~90 degrees only), 0.3 x 1 ring
    /// 0.96 / 0.002; bunny 0.98 / 0 -> 1.0 / 0.001.
    double hysteresis_threshold = 0.3;
    int hysteresis_rings = 1;
    /// Boundary points closer than this (spacings) belong to the same loop (§10 step 8).
    double link_distance = 3.0;
    int min_loop_points = 8;  ///< smaller components are noise (§10 step 8)
    /// Small loop: rim diameter <= this x spacing ... The measured diameter includes the rim's
    /// width (about two spacings each side), so 20 = holes up to about 15 spacings across
    /// (§10 step 10 says 15 for the hole itself).
    double small_max_diameter = 20.0;
    int small_max_points = 200;  ///< ... and at most this many rim points [M]
    /// Visibility: a sensor sees a loop's region when the region faces it within this angle,
    /// it lies in the sensor's frustum (when intrinsics are known) and no point lies within
    /// `ray_clearance` x spacing of the line of sight.
    double visible_max_angle_deg = 60.0;
    double ray_clearance = 1.0;
    void check() const;
};

struct BoundaryResult {
    double spacing_m = 0;
    std::vector<float> p_angle, p_halfdisk, p_shape, probability;
    std::vector<std::uint8_t> boundary;  ///< final flag: in a loop of >= min_loop_points
    /// Per point: the two neighbours bounding the largest angular gap (UINT32_MAX if none).
    std::vector<std::uint32_t> gap_a, gap_b;
    std::vector<BoundaryLoop> loops;
    SurfaceGradient gradient;
};

/// Runs §9 + §10 on `points`. `sensors` (may be empty) feeds the visibility test and the
/// normal orientation. Throws InputError for fewer than 4 points or non-finite coordinates,
/// AlgorithmError("cancelled") when `progress` returns false. Report: spacing, counts per
/// stage (candidates, after coherence, in loops), loops per class and kind, time_s.
BoundaryResult detect_boundaries(const SurfacePoints& points,
                                 const std::vector<SensorView>& sensors,
                                 const BoundaryOptions& options, Report* report = nullptr,
                                 const Progress& progress = {});

/// Boundary probabilities (angle, half-disk, shape, combined) of point i against an arbitrary
/// neighbour list (used again while filling, §11). Neighbours are projected on the plane
/// (e1, e2) of i. Writes the gap-bounding neighbours and the sorted gaps when asked.
struct PointCriteria {
    float p_angle = 0, p_halfdisk = 0, p_shape = 0, probability = 0;
    std::uint32_t gap_a = UINT32_MAX, gap_b = UINT32_MAX;
};
PointCriteria point_criteria(const Eigen::Vector3d& p, const Eigen::Vector3d& e1,
                             const Eigen::Vector3d& e2, const std::vector<Eigen::Vector3d>& all,
                             const std::uint32_t* neighbours, std::size_t count,
                             const BoundaryOptions& options);

/// Does `sensor` have a clear, front-facing line of sight to the region (centre, normal, radius)?
/// Front-facing: within max_angle_deg of the normal (either side); in the depth camera's
/// frustum when its intrinsics are known; no point of `tree` within ray_clearance x spacing of
/// the line of sight beyond the region's half radius. Used by §10 (loops) and §12/§13 (holes).
bool sensor_sees_region(const SensorView& sensor, const Eigen::Vector3d& centre,
                        const Eigen::Vector3d& normal, double radius_m, double spacing,
                        const internal::KdTree& tree, double max_angle_deg, double ray_clearance);

/// The options check of sensor_sees_region's parameters, for the options structs that carry
/// them: InputError "<who>: visibility angle must be in (0, 90) degrees, got <value>" or "<who>:
/// ray clearance must be in (0, 20] spacings, got <value>" (check_range).
void check_visibility(const char* who, double max_angle_deg, double ray_clearance);

}  // namespace rgbd::holes
