// Synthetic depth views for the registration tests: ray-cast per pixel of a Kinect-v2-like
// depth camera (512x424, f = 365.5) against an analytic surface (a bumpy ellipsoid, or a
// textured cylinder whose geometry slides about and along its axis), Gaussian depth noise,
// optional colour from a function of the world point, points in the sensor frame (x right,
// y down, z forward).
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <random>

#include "toolkit/point_cloud.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::test {

/// Ellipsoid (semi-axes 0.12, 0.16, 0.10 m) with smooth non-symmetric bumps, centred at `centre`.
struct BumpyEllipsoid {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();

    /// Radius of the surface along unit direction u.
    double radius(const Eigen::Vector3d& u) const {
        const double e =
            1.0 / std::sqrt(u.x() * u.x() / (0.12 * 0.12) + u.y() * u.y() / (0.16 * 0.16) +
                            u.z() * u.z() / (0.10 * 0.10));
        const double bumps = 0.06 * std::sin(5.0 * u.x() + 1.0) * std::cos(4.0 * u.y()) +
                             0.04 * std::sin(7.0 * u.z() + 3.0 * u.x()) + 0.03 * u.y() * u.y();
        return e * (1.0 + bumps);
    }
    /// Signed: > 0 outside.
    double value(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d d = p - centre;
        const double len = d.norm();
        if (len < 1e-12) return -1.0;
        return len - radius(d / len);
    }
    double max_radius() const { return 0.16 * 1.14; }
};

/// Open cylinder of radius 0.1 m about the world y axis through `centre`, 1 m tall: seen from
/// the side at mid height, the views hold no cap, so geometry cannot fix a rotation about the
/// axis or a slide along it. `colour` paints it (angle and height stripes).
struct TexturedCylinder {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    double r = 0.1, half_height = 0.5;
    double value(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d d = p - centre;
        return std::max(std::hypot(d.x(), d.z()) - r, std::abs(d.y()) - half_height);
    }
    double max_radius() const { return std::hypot(r, half_height) + 1e-3; }
    Rgb colour(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d d = p - centre;
        const double theta = std::atan2(d.z(), d.x());
        const double v = 0.5 + 0.25 * std::sin(6.0 * theta) + 0.2 * std::cos(25.0 * d.y() + theta);
        const auto g = static_cast<std::uint8_t>(std::clamp(v, 0.0, 1.0) * 255.0);
        return {g, static_cast<std::uint8_t>(0.8 * g), static_cast<std::uint8_t>(0.6 * g)};
    }
};

/// Camera looking at `target` from `eye`, with world "up" = +y (image y = down).
inline Pose look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
    return rgbd::look_at(eye, target, Eigen::Vector3d::UnitY());
}

/// Ray-cast view of the surface from the camera at `world_from_sensor`; every `stride`-th pixel.
/// With `colour`, every point gets colour(world point).
template <class Shape>
PointCloud render_view(const Shape& shape, const Pose& world_from_sensor, int id,
                       double noise_sigma_m, std::uint32_t seed, int stride = 1,
                       const std::function<Rgb(const Eigen::Vector3d&)>& colour = {}) {
    PointCloud cloud;
    cloud.view.id = id;
    cloud.view.sensor = "synthetic-" + std::to_string(id);
    cloud.view.frame = ViewFrame::kSensor;
    cloud.view.world_from_sensor = world_from_sensor;
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, noise_sigma_m);
    const double f = 365.5, cx = 256.0, cy = 212.0;
    const Eigen::Vector3d eye = world_from_sensor.translation();
    const double rmax = shape.max_radius();
    std::optional<PointCloud::ColorMaps> colours;
    if (colour) colours = cloud.add_colors();
    for (int v = 0; v < 424; v += stride)
        for (int u = 0; u < 512; u += stride) {
            const Eigen::Vector3d ray_s((u - cx) / f, (v - cy) / f, 1.0);
            const Eigen::Vector3d dir = (world_from_sensor.linear() * ray_s).normalized();
            // Bounding sphere.
            const Eigen::Vector3d oc = eye - shape.centre;
            const double b = oc.dot(dir), c = oc.squaredNorm() - rmax * rmax;
            if (b * b - c < 0) continue;
            double t0 = std::max(0.0, -b - std::sqrt(b * b - c));
            const double t1 = -b + std::sqrt(b * b - c);
            const double step = 0.002;
            double prev = shape.value(eye + t0 * dir);
            double hit = -1;
            for (double t = t0 + step; t <= t1 + step; t += step) {
                const double val = shape.value(eye + t * dir);
                if (prev > 0 && val <= 0) {
                    double lo = t - step, hi = t;
                    for (int k = 0; k < 40; ++k) {
                        const double mid = 0.5 * (lo + hi);
                        (shape.value(eye + mid * dir) > 0 ? lo : hi) = mid;
                    }
                    hit = 0.5 * (lo + hi);
                    break;
                }
                prev = val;
            }
            if (hit < 0) continue;
            const double z = hit * dir.dot(world_from_sensor.linear().col(2)) + noise(rng);
            const auto idx = *cloud.points.insert(to_point(ray_s * z));
            if (colour) colours->set(idx, colour(eye + hit * dir));
        }
    return cloud;
}

/// Rotation of `deg` degrees about a random axis, and a translation of `m` metres in a random
/// direction.
inline Pose random_motion(double deg, double m, std::mt19937& rng) {
    std::normal_distribution<double> n(0.0, 1.0);
    const Eigen::Vector3d axis = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    const Eigen::Vector3d dir = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    Pose pose = Pose::Identity();
    pose.linear() = Eigen::AngleAxisd(deg * M_PI / 180.0, axis).toRotationMatrix();
    pose.translation() = m * dir;
    return pose;
}

}  // namespace rgbd::test
