// Object extraction in the world frame (docs/algorithms.md §3 step 2 [M]): the sensors of a ring,
// a turntable or a person turning in front of one camera all look at the object, so the point
// nearest to all their optical axes is the object centre; points farther than a radius from
// it (walls, floor, flying-pixel streaks towards the background) are not the object.
// See also: algorithms/frames/depth_to_cloud.hpp (the depth window of §3 step 1).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "toolkit/point_cloud.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/report.hpp"

namespace rgbd::frames {

/// The point nearest (least squares) to the optical axes (camera +z) of the given sensor
/// poses. Returns nullopt when fewer than two poses are given, the axes are (nearly) parallel,
/// or the point lies behind one of the cameras.
std::optional<Eigen::Vector3d> axes_convergence_point(const std::vector<Pose>& world_from_sensor);

/// Keeps the points of a view whose world position (view.world_from_sensor applied to a
/// sensor-frame view) lies within `radius_m` of `centre_world`. With `mark`, sets the `noise`
/// flag instead of deleting. Throws InputError for a sensor-frame view without pose or a
/// non-positive radius. Report: removed count.
Report crop_to_sphere(PointCloud& cloud, const Eigen::Vector3d& centre_world, double radius_m,
                      bool mark = false);

}  // namespace rgbd::frames
