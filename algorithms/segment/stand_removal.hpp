// Removal of the stand an object stands on (a turntable platter, a table top) from aligned
// views: the support plane found by RANSAC (Fischler & Bolles 1981) among the lowest points,
// its normal constrained near the cameras' up, refined by least squares on its inliers; every
// point on or below it (plus a margin) is removed. Issue 23 (turntable captures).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::segment {

struct StandOptions {
    double max_tilt_deg = 15.0;      ///< plane normal within this angle of the up estimate, deg
    double inlier_m = 0.0015;        ///< RANSAC inlier distance to the plane, metres
    double margin_m = 0.0025;        ///< points up to this above the plane are removed too, m
    double search_fraction = 0.35;   ///< the plane is searched in the lowest this share of the
                                     ///< height range (2nd-98th percentile of heights along up)
    double min_support = 0.03;       ///< accept a plane only with at least this share of all
                                     ///< points as inliers
    double min_above = 0.2;          ///< ... and at least this share more than 10 margins above
    int iterations = 400;            ///< RANSAC hypotheses
    int max_samples = 40000;         ///< points the hypotheses are scored on (evenly strided)
    std::uint64_t seed = 1;          ///< RANSAC's sampling seed (deterministic)
    double contact_band_m = 0.0015;  ///< contact_points(): the band above the cut that is
                                     ///< carried down to the plane, metres

    /// Throws InputError for values out of range.
    void check() const;
};

/// The support plane: unit normal n (pointing up, away from the stand) and offset d, with
/// n . p + d the signed height of p above the plane, metres.
struct SupportPlane {
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    double offset = 0.0;
    std::size_t inliers = 0;  ///< points within inlier_m of the refined plane
};

/// The cameras' up in the world: the mean of -y (image up) of every view's world_from_sensor
/// rotation, normalised; nullopt when no view has a pose or the mean vanishes. Around a
/// turntable or a ring the horizontal parts of the tilted cameras' up cancel.
std::optional<Eigen::Vector3d> cameras_up(const std::vector<PointCloud>& views);

/// Finds the support plane in the views (world coordinates: each view's points, moved by its
/// world_from_sensor when it is in the sensor frame) around `up`; nullopt when no plane passes
/// the acceptance tests (min_support, min_above). Throws InputError for a non-finite point.
std::optional<SupportPlane> find_support_plane(const std::vector<PointCloud>& views,
                                               const Eigen::Vector3d& up,
                                               const StandOptions& options = {});

/// Points that carry the object's walls down to the support plane after remove_stand cut them
/// `margin_m` above it: every point of `views` whose height above `plane` lies in
/// [margin_m, margin_m + contact_band_m) and whose normal is within 60 deg of horizontal
/// (a wall; any point when the view has no normals) is copied at heights 0, margin/3 and
/// 2 margin/3 straight down along the plane normal, colour and normal kept, flagged
/// synthetic. One world-frame view (sensor "rgbd-stand", id one above the largest); empty
/// when no point qualifies.
PointCloud contact_points(const std::vector<PointCloud>& views, const SupportPlane& plane,
                          const StandOptions& options = {});

/// Finds the support plane (up from cameras_up) and deletes every point whose signed height
/// above it is below margin_m, all properties kept aligned. The report: "found" (bool),
/// "plane" {normal, offset_m, inliers}, "tilt_deg" (plane normal vs the cameras' up),
/// "removed" and per view "removed", "time_s"; "note" when nothing was removed and why.
/// `plane_out`, when given, receives the plane (nullopt when none was found).
Report remove_stand(std::vector<PointCloud>& views, const StandOptions& options = {},
                    const Progress& progress = {},
                    std::optional<SupportPlane>* plane_out = nullptr);

}  // namespace rgbd::segment
