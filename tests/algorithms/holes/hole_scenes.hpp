// Shared by the hole tests of this folder: the sample spacing of their surfaces, a sensor that
// looks at a point, and the distance to an ellipsoid (test code, in the namespace it tests).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "algorithms/holes/hole_detection.hpp"

namespace rgbd::holes {

/// Spacing of the test surfaces' samples, metres.
inline constexpr double kSpacing = 0.002;

/// A sensor at `centre` looking at `target` (camera: z forward, y down as far as possible).
inline SensorView look_at(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
    const Eigen::Vector3d zc = (target - centre).normalized();
    const Eigen::Vector3d yc = (Eigen::Vector3d(0, 0, -1) + zc.z() * zc).normalized();
    SensorView v;
    v.world_from_sensor.linear().col(0) = yc.cross(zc);
    v.world_from_sensor.linear().col(1) = yc;
    v.world_from_sensor.linear().col(2) = zc;
    v.world_from_sensor.translation() = centre;
    return v;
}

/// Distance of `p` to the surface of the ellipsoid with semi-axes `axes`, first order:
/// |f| / |grad f| with f = |p / a| - 1 (exact on a sphere up to O(d^2)).
inline double ellipsoid_distance(const Eigen::Vector3d& axes, const Eigen::Vector3d& p) {
    const Eigen::Vector3d q = p.cwiseQuotient(axes);
    const Eigen::Vector3d g = q.cwiseQuotient(axes) / q.norm();
    return std::abs(q.norm() - 1.0) / g.norm();
}

}  // namespace rgbd::holes
