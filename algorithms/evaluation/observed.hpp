// How well a mesh explains a capture's own observations, for real captures without ground
// truth (rgbd-eval --observed): the observed subject points (observed_subject) against the
// mesh surface, both ways: the share of observations the mesh explains, the share of its area
// an observation supports, and the area nothing supports (docs/method.md, evaluation).
// The directions are those of accuracy / completeness (Aanaes et al., DTU, IJCV 2016) with
// the observations in place of a reference surface; distances as in metrics.hpp.
// See also: metrics.hpp (compare_to_reference), mesh_quality.hpp, segment/stand_removal.hpp.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/report.hpp"

namespace rgbd::evaluation {

/// Per-pixel subject labels (gt/<sensor>/segment/NNNNNN.png of rgbd-synth).
inline constexpr std::uint8_t kLabelSubject = 1;
inline constexpr std::uint8_t kLabelSupport = 2;
inline constexpr std::uint8_t kLabelBackground = 3;

/// Options of observed_subject().
struct SubjectOptions {
    double radius_m = 1.0;          ///< radius of the vertical cylinder around the centre, m
    double max_tilt_deg = 15.0;     ///< ground plane normal within this angle of the cameras' up
    double ground_inlier_m = 0.01;  ///< RANSAC inlier distance of the ground plane, m
    double ground_margin_m = 0.02;  ///< points up to this above the ground plane are dropped, m
    /// The ground plane must be dominant: at least this share of the cylinder's points are its
    /// inliers (a lower share is the curved or cut bottom of the subject, not the ground).
    double ground_min_support = 0.10;
    /// Look for the ground plane at all. Off when the views were already cut to the subject by
    /// object masks (there is no ground left, and the lowest part of the subject may be flat
    /// enough to pass for one).
    bool remove_ground = true;

    /// Throws InputError for a non-positive or non-finite value, or a tilt outside (0, 90).
    void check() const;
};

/// Keeps in every view only the observed subject points, in place (all properties follow):
///  - with labels (one CV_8UC1 image per view on the view's depth grid, found through each
///    point's `pixel` property): the points labelled kLabelSubject;
///  - otherwise, when `centre` is given: the points inside the vertical cylinder of radius
///    radius_m around `centre` (vertical = segment::cameras_up of the views), minus the
///    ground: the dominant plane among the lowest points of the cylinder whose normal is
///    within max_tilt_deg of the up (segment::find_support_plane), every point less than
///    ground_margin_m above it dropped (none when no plane passes find_support_plane's tests,
///    or remove_ground is off);
///  - without labels and centre: every point (still minus a ground plane when the views have
///    poses to tell the up).
/// @param views   views in the sensor frame with world_from_sensor, or in the world frame.
/// @param labels  empty (no labels) or one image per view, each non-empty.
/// @param centre  where the sensors' axes converge (pipeline::object_centre), world frame.
/// @return {"selection": "labels" | "cylinder" | "all", "points_in", "points",
///          "radius_m", "centre", "up", "ground": {found, normal, offset_m, removed}}.
/// @throws InputError when the labels do not match the views (count, size, type) or a view
///         lacks the pixel property the labels need.
Report observed_subject(std::vector<PointCloud>& views, const std::vector<cv::Mat>& labels,
                        const std::optional<Eigen::Vector3d>& centre,
                        const SubjectOptions& options = {});

/// Options of observed_metrics().
struct ObservedOptions {
    /// Thresholds tau (metres): the first is the main one, the others are reported as detail.
    std::vector<double> taus_m{0.020, 0.005};
    /// Mesh area farther than this times tau from every observation is unsupported.
    double unsupported_factor = 2.0;
    /// Area-uniform samples drawn on the mesh for the area shares.
    std::size_t samples = 200000;
    std::uint64_t seed = 1;  ///< seed of the samples

    /// Throws InputError for no / non-positive / non-finite taus, a factor < 1, samples == 0
    /// or > 1e8.
    void check() const;
};

/// The scores at one tau.
struct ObservedScores {
    double tau_m = 0.0;
    double explained = 0.0;  ///< share of the observed points within tau of the mesh surface
    std::size_t explained_points = 0;
    double covered = 0.0;  ///< share of the mesh area within tau of an observed point
    double covered_area_m2 = 0.0;
    double unsupported_area_fraction = 0.0;  ///< share of the mesh area farther than
                                             ///< unsupported_factor * tau from every point
    double unsupported_area_m2 = 0.0;
};

/// Result of observed_metrics().
struct ObservedMetrics {
    std::vector<ObservedScores> thresholds;  ///< in the order of ObservedOptions::taus_m
    std::size_t observed_points = 0;
    double mesh_area_m2 = 0.0;  ///< area of the triangles of positive area
    std::size_t samples = 0;
    double unsupported_factor = 2.0;
    double observed_to_mesh_median_m = 0.0;  ///< median distance observation -> surface
    double mesh_to_observed_median_m = 0.0;  ///< median distance surface sample -> observation
    double time_s = 0.0;

    /// The first tau's scores at the top level (tau_mm, explained, explained_points, covered,
    /// covered_area_m2, unsupported_area_fraction, unsupported_area_m2, unsupported_beyond_mm)
    /// beside mesh_area_m2, observed_points, samples and the medians (mm); every further tau
    /// as "at_<tau>mm": {...the same scores}.
    Report to_json() const;
};

/// Scores `mesh` against observed points (world frame): explained (points -> exact
/// point-to-triangle distance, zero-area triangles ignored), covered and unsupported area
/// (area-uniform samples of the mesh -> nearest observed point, kd-tree; each sample stands
/// for mesh_area / samples). Deterministic for a seed, any thread count.
/// @throws InputError for a mesh without faces, with a non-triangle face or no positive area,
///         no observed points or a non-finite point.
ObservedMetrics observed_metrics(const Mesh& mesh, const std::vector<Eigen::Vector3d>& observed,
                                 const ObservedOptions& options = {});

}  // namespace rgbd::evaluation
