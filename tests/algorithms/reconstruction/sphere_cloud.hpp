// Test data: Fibonacci samples of a sphere with outward normals, red upper (z > 0) and blue
// lower hemisphere; optionally every 10th point flagged `synthetic` and coloured green.
#pragma once

#include <cmath>
#include <optional>
#include <random>

#include "toolkit/point_cloud.hpp"

namespace rgbd::test {

/// An empty view 0 in the world frame with normal and colour maps, to be filled.
inline PointCloud empty_world_view() {
    PointCloud cloud;
    cloud.view.id = 0;
    cloud.view.frame = ViewFrame::kWorld;
    cloud.points.add_normal_map();
    cloud.add_colors();
    return cloud;
}

inline PointCloud coloured_sphere(int n, double radius, bool with_synthetic = false) {
    PointCloud cloud = empty_world_view();
    cloud.view.sensor = "merged";
    auto colors = cloud.colors();
    std::optional<PointCloud::Uint8Map> synthetic;
    if (with_synthetic) synthetic = cloud.add_flag(prop::kSynthetic);
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n;
        const double r = std::sqrt(1.0 - z * z);
        const Eigen::Vector3d u(r * std::cos(golden * i), r * std::sin(golden * i), z);
        auto it = cloud.points.insert(to_point(radius * u));
        cloud.points.normal(*it) = to_vector(u);
        colors.set(*it, z > 0 ? Rgb{220, 20, 20} : Rgb{20, 20, 220});
        if (with_synthetic && i % 10 == 0) {
            (*synthetic)[*it] = 1;
            colors.set(*it, Rgb{0, 255, 0});
        }
    }
    return cloud;
}

/// Fibonacci sphere samples (radius `radius`, outward normals, grey) with Gaussian noise of
/// `sigma` metres along the normal (seeded), without the points above z = cap_z * radius
/// (cap_z >= 1 keeps the whole sphere) nor those below z = base_z * radius.
inline PointCloud noisy_sphere(int n, double radius, double sigma, double cap_z = 1.0,
                               unsigned seed = 1, double base_z = -1.0) {
    PointCloud cloud = empty_world_view();
    auto colors = cloud.colors();
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, sigma);
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n;
        if (z > cap_z || z < base_z) continue;
        const double r = std::sqrt(1.0 - z * z);
        const Eigen::Vector3d u(r * std::cos(golden * i), r * std::sin(golden * i), z);
        auto it = cloud.points.insert(to_point((radius + noise(rng)) * u));
        cloud.points.normal(*it) = to_vector(u);
        colors.set(*it, Rgb{128, 128, 128});
    }
    return cloud;
}

/// A thin plate (a fin): the closed surface of the box |x| <= a, |y| <= b, |z| <= t / 2,
/// sampled on a jittered grid of `step` on every face with outward normals, plus Gaussian
/// noise of `sigma` along the normal. Top (z > 0) red, bottom blue, rim green.
inline PointCloud thin_plate(double a, double b, double t, double step, double sigma,
                             unsigned seed = 1) {
    PointCloud cloud = empty_world_view();
    auto colors = cloud.colors();
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, sigma);
    std::uniform_real_distribution<double> jitter(-0.25 * step, 0.25 * step);
    auto add = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& n, Rgb c) {
        auto it = cloud.points.insert(to_point(p + noise(rng) * n));
        cloud.points.normal(*it) = to_vector(n);
        colors.set(*it, c);
    };
    const double h = t / 2;
    for (double x = -a + step / 2; x < a; x += step)
        for (double y = -b + step / 2; y < b; y += step) {
            add({x + jitter(rng), y + jitter(rng), h}, {0, 0, 1}, Rgb{220, 20, 20});
            add({x + jitter(rng), y + jitter(rng), -h}, {0, 0, -1}, Rgb{20, 20, 220});
        }
    for (double z = -h + step / 2; z < h; z += step) {
        for (double x = -a + step / 2; x < a; x += step) {
            add({x + jitter(rng), b, z}, {0, 1, 0}, Rgb{20, 220, 20});
            add({x + jitter(rng), -b, z}, {0, -1, 0}, Rgb{20, 220, 20});
        }
        for (double y = -b + step / 2; y < b; y += step) {
            add({a, y + jitter(rng), z}, {1, 0, 0}, Rgb{20, 220, 20});
            add({-a, y + jitter(rng), z}, {-1, 0, 0}, Rgb{20, 220, 20});
        }
    }
    return cloud;
}

}  // namespace rgbd::test
