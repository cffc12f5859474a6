// Object extraction over all views of a frame set (docs/algorithms.md §3 steps 2-3 [M]; issue 35):
// the subject is what the sensors look at together, standing on the ground, and nothing else.
//  1. Ground: the lowest large plane whose normal lies near the cameras' up (RANSAC, Fischler and
//     Bolles 1981, over the lower part of the scene), refitted per view in that view's own frame
//     (so calibration error between views does not widen the cut), and every point of a view
//     less than a noise margin above its plane removed: ground_sigmas x the sensor's sigma_z at
//     the point's depth and incidence angle, plus the plane fit's RMS residual. A turntable's
//     platter or a table top under the object is found the same way when it is the lowest large
//     plane in view. Flat means: the points facing the plane lie about it within
//     ground_flat_sigmas of the sensor's own sigma_z at their depth and incidence (robust).
// 1b. Walls: large planes of any orientation, equally flat (the bound scaled by the ground's own
//     flatness: the ground shows how noisy the real sensor is), with every sensor in front of
//     them and (almost) nothing behind them, pooled and in each view's own refit, cut the same
//     way (the bin a subject stands in).
//  2. Connected regions of what is left, pooled over the views in the world frame: a voxel grid
//     (edge from the sensors' pixel footprint at the scene's median depth), voxels holding at
//     least `solid_points` points linked by 26-adjacency (sparse flying-pixel streaks link
//     nothing), points in thinner voxels attached to a solid neighbour.
//  3. The subject: the region with the most points inside the co-visible core, the volume that
//     at least `core_share` of the views (and at least two) hold in their viewing frusta
//     (pinhole image bounds, depth up to what the view measured); then every other region that
//     lies mostly in the core and within `join_gap_m` of the subject (an instrument, a bow, a
//     chair, the other objects of a bin). Walls, other people and clutter away from it, far
//     parts of the floor and the room are dropped. Its extent comes from the data: nothing
//     about the subject's size or shape is assumed.
// Peers: PCL SACSegmentation + EuclideanClusterExtraction, Open3D segment_plane +
// cluster_dbscan (both single-view, fixed thresholds). See also:
// algorithms/segment/stand_removal.hpp (the stand under a turntable object, after alignment),
// algorithms/frames/object_extraction.hpp (the fixed sphere crop, --crop-radius-m).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::segment {

struct SubjectOptions {
    bool remove_ground = true;          ///< find and remove the ground (false: --keep-ground)
    bool select_subject = true;         ///< keep only the subject's regions (false: ground only)
    double ground_max_tilt_deg = 20.0;  ///< ground normal within this of the cameras' up, deg
    /// RANSAC inlier band of the pooled plane, metres: wide enough for calibration error between
    /// views (1.5 deg at 2 m is 5 cm); each view then refits its own plane within it.
    double ground_band_m = 0.05;
    double ground_min_share = 0.02;  ///< the plane holds at least this share of all points
    double ground_sigmas = 3.0;      ///< cut margin in sigma_z of the sensor noise at the point
    /// The ground is flat: the views' median robust deviation of the points facing it, in
    /// sigma_z(z, theta) of the sensor at each point, is at most this.
    double ground_flat_sigmas = 3.0;
    /// Walls (step 1b): large flat planes with every sensor in front of them and at most this
    /// share of the points more than a band behind them are cut like the ground.
    bool remove_walls = true;
    double wall_max_behind_share = 0.05;
    /// ... and, in the median of the views that see it, at most this share of a view's points
    /// lie behind it where the wall would hide them: their line of sight crosses the plane
    /// inside the convex hull of the wall's own points (the APC shelf's side walls: 0.00-0.04%;
    /// planes through a box leaning on a wall: 1.7-6.5%).
    double wall_max_through_share = 0.005;
    /// The candidates refused as not flat or seen through may be slices through a wall and what
    /// leans on it: their samples are searched again with this narrower voting cone, degrees.
    double wall_split_tilt_deg = 10.0;
    double ground_min_margin_m = 0.003;  ///< the margin is never less than this, metres
    double voxel_m = 0.0;                ///< connectivity voxel, metres; 0 = 3 pixel footprints at
                                         ///< the median depth, at least 5 mm
    int solid_points = 2;                ///< a voxel links its neighbours with at least this many
    double core_share = 0.5;  ///< the co-visible core: inside the frusta of this share of the views
    double join_gap_m = 0.1;  ///< regions within this of the subject may join it, metres
    double join_core_share = 0.5;  ///< ... when at least this share of their points is in the core
    /// The override of the regions: with crop_radius_m > 0, the points farther than it from
    /// crop_centre (world frame) are removed and no region is selected (--crop-radius-m).
    std::optional<Eigen::Vector3d> crop_centre;
    double crop_radius_m = 0.0;
    int iterations = 500;     ///< RANSAC hypotheses
    int max_samples = 80000;  ///< points the hypotheses are scored on (evenly strided)
    std::uint64_t seed = 1;   ///< RANSAC's sampling seed (deterministic)

    /// Throws InputError for values out of range.
    void check() const;
};

/// A view's ground plane in its own sensor frame: n . p + d is the height of p above it
/// (metres), and the cut margin used.
struct ViewGround {
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    double offset = 0.0;
    double margin_m = 0.0;  ///< the median cut margin of the view's ground points
};

/// The metadata line a view carries its ground plane in (sensor frame):
/// `rgbd:ground.plane nx ny nz offset_m margin_m`.
inline constexpr const char* kGroundKey = "rgbd:ground.plane ";
/// The ground plane a view's metadata carries, if any. InputError for a malformed line.
std::optional<ViewGround> view_ground(const PointCloud& view);
/// The ground in the world frame from the views' planes (each moved by its view's current
/// world_from_sensor; views already in the world frame used as they are): the mean normal and
/// offset, and the largest margin. nullopt when no view carries one.
std::optional<ViewGround> world_ground(const std::vector<PointCloud>& views);

/// Extracts the subject from views in their sensor frames with (initial) poses: removes the
/// ground (writing each view's plane into its metadata, kGroundKey) and everything that is not
/// the subject's regions. `noise` gives each view's sensor noise model (one entry per view, or
/// one for all). With `mark` the removed points get the `noise` flag instead of being deleted.
/// Views without a pose are left as they are (noted in the report). Throws InputError when
/// nothing is left above the ground ("nothing above the ground") and for non-finite points.
/// Report: ground {found, normal, offset_m, tilt_deg, sample_inliers, removed, views: [{view,
/// removed, margin_m, rms_m, facing, flatness_sigmas}], fit_rms_m, flatness_sigmas, flat_views},
/// walls [{normal, offset_m, sample_inliers, behind_share, flatness_sigmas,
/// flatness_bound_sigmas, view_behind_share, flat_views, found, removed, note}] (step 1b, with the
/// subject's selection), crop {radius_m, removed}, voxel_m, core_views, regions, subject_regions,
/// removed, kept, views
/// [{view, removed, kept}], note, time_s. `removed_world`, when given, receives the removed points
/// in the world frame (at most 200,000, evenly strided).
Report extract_subject(std::vector<PointCloud>& views,
                       const std::vector<denoise::NoiseModel>& noise,
                       const SubjectOptions& options = {}, bool mark = false,
                       const Progress& progress = {},
                       std::vector<Eigen::Vector3d>* removed_world = nullptr);

}  // namespace rgbd::segment
