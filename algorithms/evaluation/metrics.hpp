// Reconstruction and pose metrics against ground truth: Chamfer, Hausdorff (max and 95th
// percentile), accuracy / completeness, precision / recall / F-score at thresholds, invented
// surface, normal consistency; rotation and translation errors of camera poses.
//
// Definitions: docs/algorithms.md §7 and §15, docs/method.md. F-score at tau as in Knapitsch et
// al., "Tanks and Temples" (SIGGRAPH 2017); accuracy / completeness as in Aanaes et al., "Large-
// scale data for multiple-view stereopsis" (DTU, IJCV 2016); pose alignment by Umeyama, "Least-
// squares estimation of transformation parameters between two point patterns" (PAMI 1991).
// See also: CGAL `PMP::approximate_Hausdorff_distance`, Open3D
// `compute_point_cloud_distance`, PDAL `kernels/HausdorffKernel.cpp`.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/report.hpp"

namespace rgbd::evaluation {

/// Samples `count` points uniformly by area on the triangles of `mesh` (zero-area faces get
/// none). Deterministic for a given seed and any thread count.
/// @throws InputError when the mesh has a non-triangle face or no positive area.
std::vector<Eigen::Vector3d> sample_surface(const Mesh& mesh, std::size_t count,
                                            std::uint64_t seed);

/// Options of compare_to_reference().
struct MetricOptions {
    /// Thresholds tau (metres) for precision, recall and F-score.
    std::vector<double> taus_m{0.002, 0.005};
    /// Area-uniform samples drawn on each mesh (result and reference).
    std::size_t samples = 200000;
    /// Seed of the surface samples.
    std::uint64_t seed = 1;
    /// Result surface farther than this from the reference counts as invented (metres).
    double invented_tau_m = 0.005;

    /// Throws InputError for no / non-positive / non-finite taus, samples == 0 or > 1e8.
    void check() const;
};

/// Scores at one threshold.
struct ThresholdScores {
    double tau_m = 0.0;
    double precision = 0.0;  ///< share of result samples within tau of the reference
    double recall = 0.0;     ///< share of reference samples within tau of the result
    double fscore = 0.0;     ///< 2PR / (P + R), 0 when both are 0
};

/// Distance statistics of one direction (metres).
struct DistanceStats {
    double mean = 0.0, median = 0.0, p95 = 0.0, max = 0.0;
};

/// Result of compare_to_reference().
struct SurfaceMetrics {
    DistanceStats accuracy;        ///< result samples -> reference surface
    DistanceStats completeness;    ///< reference samples -> result (surface or points)
    double chamfer_m = 0.0;        ///< (accuracy.mean + completeness.mean) / 2
    double hausdorff_m = 0.0;      ///< max of both maxima
    double hausdorff_p95_m = 0.0;  ///< max of both 95th percentiles
    std::vector<ThresholdScores> thresholds;
    double invented_tau_m = 0.0;
    /// Share of the result's area (cloud: of its points) farther than invented_tau_m.
    double invented_surface_fraction = 0.0;
    /// Mean |n_result . n_reference| over both directions, when the result has normals
    /// (mesh faces, or a cloud with a normal map).
    std::optional<double> normal_consistency;
    std::size_t result_samples = 0;
    std::size_t reference_samples = 0;
    double time_s = 0.0;

    /// snake_case keys with units: chamfer_m, hausdorff_m, hausdorff_p95_m, accuracy_*_m,
    /// completeness_*_m, precision_2mm, recall_2mm, fscore_2mm, ... (tau in mm; a fractional
    /// tau is written with 'p', 0.5 mm -> "0p5mm"), invented_surface_fraction, ...
    Report to_json() const;
};

/// Compares a result (a mesh, or else a point cloud) with a reference mesh.
///
/// Result -> reference: point-to-triangle distances (CGAL AABB tree) of area-uniform samples
/// of the result mesh, or of every point of the result cloud. Reference -> result: samples of
/// the reference to the result triangles (mesh) or to the nearest result point (cloud).
/// @param result_mesh    result surface, or null to use result_points.
/// @param result_points  result cloud, used when result_mesh is null (coordinates as they are:
///                       bring it into the reference frame first).
/// @param reference      ground-truth surface, triangle mesh with positive area.
/// @throws InputError for an empty or non-triangle mesh, both results null, an empty cloud or
///         non-finite coordinates.
SurfaceMetrics compare_to_reference(const Mesh* result_mesh, const PointCloud* result_points,
                                    const Mesh& reference, const MetricOptions& options);

/// Distance (metres) from every point to the surface of `reference` (exact point-to-triangle
/// distance, zero-area triangles ignored), in parallel: per-vertex error maps (rgbd-eval
/// --report, rgbd-render --scalar distance).
/// @throws InputError for an empty or non-triangle reference or a non-finite point.
std::vector<double> distances_to_surface(const std::vector<Eigen::Vector3d>& points,
                                         const Mesh& reference);

/// Distance (metres) from every point to the nearest point of `cloud` (exact, cell grids), in
/// parallel.
/// @throws InputError for an empty cloud or a non-finite point.
std::vector<double> distances_to_points(const std::vector<Eigen::Vector3d>& points,
                                        const std::vector<Eigen::Vector3d>& cloud);

/// For every point, 1 when some point of `cloud` lies within `tau` metres of it (the same
/// answer as distances_to_points(...)[i] <= tau), else 0; in parallel. A cell grid of side tau
/// answers from the 27 cells around the point and stops at the first point found, so points
/// far from the cloud cost no more than near ones (a mesh's closure, far-area shares).
/// @throws InputError for an empty cloud, a non-finite point or tau not positive and finite.
std::vector<char> within_distance(const std::vector<Eigen::Vector3d>& points,
                                  const std::vector<Eigen::Vector3d>& cloud, double tau);

/// Pose error of one sensor.
struct PoseError {
    std::string sensor;
    double rotation_deg = 0.0;
    double translation_mm = 0.0;
};

/// Result of pose_errors().
struct PoseErrors {
    std::vector<PoseError> per_sensor;  ///< sensors present in both maps, in name order
    std::vector<std::string> missing;   ///< sensors of `truth` without an estimate
    double mean_rotation_deg = 0.0, max_rotation_deg = 0.0;
    double mean_translation_mm = 0.0, max_translation_mm = 0.0;
    bool gauge_removed = false;
    /// "umeyama" (>= 3 non-collinear camera centres), "first_pose" or "none".
    std::string gauge_method = "none";
    /// The transform applied to every estimated pose before comparing (identity without gauge).
    Pose truth_from_estimate = Pose::Identity();

    Report to_json() const;
};

/// Rotation (degrees) and translation (millimetres) errors of estimated world_from_sensor poses.
///
/// @param remove_gauge  first align the estimated set to the truth by the best rigid transform
///                      of the camera centres (Umeyama / Kabsch, no scale); with fewer than 3
///                      common sensors or collinear centres, by the first common sensor's pose.
/// @throws InputError when no sensor is common to both maps or a pose is not finite.
PoseErrors pose_errors(const std::map<std::string, Pose>& estimated,
                       const std::map<std::string, Pose>& truth, bool remove_gauge);

}  // namespace rgbd::evaluation
