// Test data: Fibonacci samples of a sphere with outward normals, red upper (z > 0) and blue
// lower hemisphere; optionally every 10th point flagged `synthetic` and coloured green.
#pragma once

#include <cmath>

#include "toolkit/point_cloud.hpp"

namespace rgbd::test {

inline PointCloud coloured_sphere(int n, double radius, bool with_synthetic = false) {
    PointCloud cloud;
    cloud.view.id = 0;
    cloud.view.sensor = "merged";
    cloud.view.frame = ViewFrame::kWorld;
    cloud.points.add_normal_map();
    auto colors = cloud.add_colors();
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

}  // namespace rgbd::test
