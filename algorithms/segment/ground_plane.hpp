// The ground step of the subject extraction (docs/method.md, "Object extraction", step 1):
// the pooled ground plane of all views, its refit in each view's own frame, and the cut above
// it. Internal to algorithms/segment (subject_extraction.cpp is its only user).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "algorithms/segment/subject_extraction.hpp"

namespace rgbd::segment::detail {

/// A plane n . p + d = 0 with unit normal n.
struct Plane {
    Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
    double d = 0;
    double height(const Eigen::Vector3d& p) const { return n.dot(p) + d; }
};

/// A sample of the pooled points: its world position and its grid normal (zero: unknown).
struct GroundSample {
    Eigen::Vector3d p, n;
};

/// RANSAC for the plane within acos(cos_tilt) of `up` that holds the most of `points` within
/// `inlier` (metres), hypotheses drawn from `points`; false when no hypothesis holds 3 points.
bool ransac_plane(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& up,
                  double cos_tilt, double inlier, int iterations, std::uint64_t seed, Plane& best,
                  std::size_t& best_score);

/// The pooled ground candidate (world frame): RANSAC over the samples whose surface faces up
/// (grid normals within ground_max_tilt_deg of `up`; samples without a normal count too) for the
/// plane near `up` with the most of them within half a band; then the same below it (more than
/// two bands lower): a plane there holding at least a third as many is the lower one (the floor
/// under a table top). Refined by least squares on a band that shrinks to an eighth. Returned
/// when it holds ground_min_share of all samples (`inliers`: how many are within half a band).
/// Whether it is the ground is judged per view (ViewGroundFit), in each view's own frame: the
/// views' poses may disagree by centimetres before alignment, which spreads a pooled floor.
std::optional<Plane> pooled_ground(const std::vector<GroundSample>& samples,
                                   const Eigen::Vector3d& up, const SubjectOptions& options,
                                   std::size_t& inliers);

/// A bounding plane (world frame), docs/algorithms.md §3 step 1b: RANSAC over the samples not
/// `used` yet, any orientation, for the plane holding the most within half a band, its normal
/// turned towards the mean of `cameras` (the sensors' centres), refined by least squares on a
/// band that shrinks to an eighth; its samples within half a band are then marked `used`.
/// nullopt when it holds fewer than ground_min_share of all samples. `behind`: the samples
/// more than a band behind it (the far side from the cameras).
std::optional<Plane> pooled_bounding_plane(const std::vector<GroundSample>& samples,
                                           std::vector<std::uint8_t>& used,
                                           const Eigen::Vector3d& cameras,
                                           const SubjectOptions& options, std::uint64_t seed,
                                           std::size_t& inliers, std::size_t& behind);

/// One view's refit of the pooled plane in its sensor frame.
struct ViewGroundFit {
    Plane plane;            ///< the view's plane (the pooled one when it could not refit)
    double rms_m = 0;       ///< the noise about it the cut allows for (see below); 0 = not refitted
    std::size_t below = 0;  ///< the view's points more than half a band below the plane
    std::size_t above = 0;  ///< ... and more than half a band above it
    std::size_t points = 0;
    /// ... of those below it, the ones its surface would hide: their line of sight from the
    /// sensor crosses the plane inside the convex hull of the facing points (walls only)
    std::size_t through = 0;
    std::size_t facing = 0;  ///< the points facing the plane its flatness is measured on
    double robust_m = 0;     ///< their robust deviation about it (1.4826 x median |h|), m
    double normalized = 0;   ///< the same in units of the sensor's sigma_z at each point
};

/// Refits `pooled` (sensor frame) on one view's points `xyz` (sensor frame, metres): RANSAC
/// among the points within a band of it for the plane within 5 degrees of it that holds the
/// most within a fifth of a band (the view's own offset and tilt: a pose a few centimetres or a
/// degree off), least squares on its points within half a band, then on those within 3 RMS
/// (at least 5 mm), each within ground_max_tilt_deg of the pooled plane. Then its flatness, on
/// the points facing it (grid normals `normals`, sensor frame, one per point or none; within
/// ground_max_tilt_deg of its normal) within half a band: least squares on them, then on those
/// within 3 robust deviations; their robust deviation in metres and in units of
/// sigma_z(z, theta) of `model` at each point's depth and incidence (a floor: about the
/// sensor's noise; the curved bottom of an object: many times it). With 50 such points the
/// plane, robust_m, normalized and rms_m (= robust_m) are that fit's.
/// A `wall` (step 1b) is refitted so that what stands against it does not move its cut: its
/// least-squares planes stay within 5 degrees of the pooled one (a view that sees it at grazing
/// incidence keeps the RANSAC's orientation), each is moved to the half-sample mode of its
/// points' heights, the band of the second round is 3 noise deviations, and rms_m is the lesser
/// of robust_m and the deviation of the points behind the plane (docs/algorithms.md §3). A
/// wall's fit also counts `through` (what it would hide is not seen).
ViewGroundFit refit_view_ground(const std::vector<Eigen::Vector3d>& xyz, const Plane& pooled,
                                const std::vector<Eigen::Vector3d>& normals,
                                denoise::NoiseModel model, const SubjectOptions& options,
                                std::uint64_t seed, bool wall = false);

/// What cut_above_ground did in one view.
struct GroundCut {
    double margin_m = 0;  ///< median margin of the cut points within a margin of the plane
    std::size_t cut = 0;  ///< points it marked that were not marked before
};

/// Marks in `removed` the points of `xyz` (sensor frame) less than the noise margin above
/// `fit.plane`: ground_sigmas x the sensor's sigma_z at the point's depth and incidence, plus
/// the fit's RMS, at least ground_min_margin_m. The margin reported is the median over the cut
/// points within a margin of the plane (metres; ground_min_margin_m when none).
GroundCut cut_above_ground(const std::vector<Eigen::Vector3d>& xyz, const ViewGroundFit& fit,
                           denoise::NoiseModel model, const SubjectOptions& options,
                           std::vector<std::uint8_t>& removed);

}  // namespace rgbd::segment::detail
