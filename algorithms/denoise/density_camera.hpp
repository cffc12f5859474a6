// What one camera of a multi-view capture contributes to the expected density of the adaptive
// density filter (docs/algorithms.md §8): its depth map for the visibility test, the samples per
// unit area it would put at a point (camera_density), and a conservative test that it puts none
// anywhere in a box (surely_occluded), which lets the filter leave it out of a whole cell.
// Internal to algorithms/denoise (not installed); camera_density stays inline: it is the
// filter's innermost loop.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "toolkit/camera.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::denoise::detail {

/// Depth map of one view in its own camera, for the visibility test.
struct Camera {
    Pose sensor_from_world;
    Eigen::Matrix3d rotation;  ///< sensor_from_world's, for the hot loop
    Eigen::Vector3d translation;
    bool undistorted = true;  ///< no lens distortion: project() is the plain pinhole
    PinholeIntrinsics intrinsics;
    double focal = 0.0;
    double inv_focal = 0.0;                            ///< 1 / focal
    double focal_sq = 0.0;                             ///< focal^2
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< the camera's centre in the world frame
    bool active = false;  ///< the view has points (an empty view sees nothing)
    /// Depth map over the bounding box [x0, x0 + bw) x [y0, y0 + bh) of the view's returns,
    /// row-major; every pixel outside it, like a pixel without a return inside, is +inf. The
    /// object fills a small part of the image: a few hundred kB instead of width * height.
    int x0 = 0, y0 = 0, bw = 0, bh = 0;
    std::vector<float> depth;

    /// Sets the pose and intrinsics and what the hot loop derives from them (the depth map is
    /// the caller's); focal is the mean of fx and fy.
    void set(const Pose& world_from_sensor, const PinholeIntrinsics& k) {
        sensor_from_world = world_from_sensor.inverse();
        rotation = sensor_from_world.linear();
        translation = sensor_from_world.translation();
        centre = world_from_sensor.translation();
        intrinsics = k;
        undistorted = k.distortion.is_none();
        focal = 0.5 * (k.fx + k.fy);
        inv_focal = 1.0 / focal;
        focal_sq = focal * focal;
    }

    /// How far behind this camera's return at depth z (metres) a point may lie and still count
    /// as seen: max_depth_step_m() with tan(theta_max) hoisted out of the loop,
    /// (z / focal) tan(theta_max) + 3 sigma_z(z).
    double occlusion_tolerance(double z, NoiseModel noise_model, double tan_max) const {
        return z * inv_focal * tan_max + 3.0 * sigma_z_m(noise_model, z, 0.0);
    }
};

/// What camera c contributes to the expected density at world point p with unit normal `nrm`:
/// cos(theta) / s_d^2, the samples per unit area of a surface at incidence theta (unclamped: a
/// view that grazes the surface adds almost nothing); none when p lies outside c's image or
/// behind c's surface (occluded: c could not have measured it). Always inlined: its caller's
/// loop over the cameras is the filter's hottest (called out of line, the calls cost a third of
/// the stage).
[[gnu::always_inline]] inline std::optional<double> camera_density(const Camera& c,
                                                                   const Eigen::Vector3d& p,
                                                                   const Eigen::Vector3d& nrm,
                                                                   NoiseModel noise_model,
                                                                   double tan_max) {
    const Eigen::Vector3d q = c.rotation * p + c.translation;
    if (q.z() <= 0.0) return std::nullopt;
    // Divisions are this loop's slowest instructions: one reciprocal of the depth serves the
    // projection and the sample spacing (and the ray's length is one square root).
    const double iz = 1.0 / q.z();
    const Eigen::Vector2d uv =
        c.undistorted ? Eigen::Vector2d(c.intrinsics.fx * (q.x() * iz) + c.intrinsics.cx,
                                        c.intrinsics.fy * (q.y() * iz) + c.intrinsics.cy)
                      : c.intrinsics.project(q);
    if (!c.intrinsics.contains(uv)) return std::nullopt;
    // lround() of coordinates > -0.5.
    const int col = int(uv.x() + 0.5), row = int(uv.y() + 0.5);
    const double tol = c.occlusion_tolerance(q.z(), noise_model, tan_max);
    // The 3 x 3 window: a missing return is +inf (never NaN), which changes neither the minimum
    // nor the "seen" test; pixels outside the map's box have no return either, so are skipped.
    // The centre pixel first: a return there within tol shows the point (most points, for the
    // views that face them), and then the rest of the window cannot change the outcome.
    // Otherwise the whole window, branch-free.
    bool seen = false;
    double nearest = std::numeric_limits<double>::infinity();
    if (row >= c.y0 && row < c.y0 + c.bh && col >= c.x0 && col < c.x0 + c.bw)
        seen = std::abs(double(c.depth[std::size_t(row - c.y0) * c.bw + std::size_t(col - c.x0)]) -
                        q.z()) <= tol;
    if (!seen) {
        const int r0 = std::max(row - 1, c.y0), r1 = std::min(row + 1, c.y0 + c.bh - 1);
        const int c0 = std::max(col - 1, c.x0), c1 = std::min(col + 1, c.x0 + c.bw - 1);
        for (int rr = r0; rr <= r1; ++rr) {
            const float* line = c.depth.data() + std::size_t(rr - c.y0) * c.bw;
            for (int cc = c0; cc <= c1; ++cc) {
                const double d = line[cc - c.x0];
                nearest = std::min(nearest, d);
                seen |= std::abs(d - q.z()) <= tol;
            }
        }
    }
    const bool any = nearest < std::numeric_limits<double>::infinity();
    // Occluded: behind v's surface, so v could not have measured it.
    if (any && !seen && q.z() > nearest + tol) return std::nullopt;
    // cos(theta) / s_d^2 with the ray from the camera to the point (world frame), cos(theta) =
    // |nrm . ray| / |ray|, and the sample spacing s_d = z / focal.
    const Eigen::Vector3d ray = p - c.centre;
    return std::abs(nrm.dot(ray)) * (c.focal_sq * iz * iz) / std::sqrt(ray.squaredNorm());
}

/// Whether camera c surely contributes nothing to every point inside the box [lo, hi] (world
/// frame): the box lies in front of c and every point of it projects to a window of c's depth
/// map whose returns are all nearer than the point by more than its occlusion tolerance, so
/// camera_density() would find it occluded. Conservative: false whenever unsure (a lens
/// distortion, the box crossing the image plane or the map's box, a missing return at a
/// window's centre, a return within the tolerance). Bounds: the box in camera coordinates from
/// its centre and half extents; x / z and y / z over that box from its corners (the pinhole
/// projection keeps a box in front of the camera within their range); the tolerance at the box's
/// nearest and farthest depth (dz_max(z) is convex in z for every noise model, so its maximum
/// over the range is at an end); margins of 1e-6 px and 1e-7 m absorb rounding.
bool surely_occluded(const Camera& c, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                     NoiseModel noise_model, double tan_max);

}  // namespace rgbd::denoise::detail
