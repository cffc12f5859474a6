#include "algorithms/reconstruction/point_budget.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "algorithms/sampling/voxel_downsample.hpp"

namespace {

using rgbd::PointCloud;

/// The budget's definition, tried in turn: the first voxel of ŝ sqrt(n / max) x 1.1^k whose
/// down-sampling holds at most max points.
double first_fitting_voxel(const PointCloud& cloud, std::size_t max_points, double spacing) {
    double voxel = spacing * std::sqrt(static_cast<double>(cloud.size()) / max_points);
    for (int k = 0; k < 60; ++k, voxel *= 1.1)
        if (rgbd::sampling::voxel_downsample(cloud, voxel).size() <= max_points) return voxel;
    return 0.0;
}

PointCloud cloud_of(const std::vector<Eigen::Vector3d>& points) {
    PointCloud cloud;
    for (const auto& p : points) cloud.points.insert(rgbd::to_point(p));
    return cloud;
}

/// `copies` noisy samplings of one square (views overlapping on a surface): the voxel count
/// falls as 1 / voxel^2, and the overlap makes the first voxel far too small.
PointCloud overlapping_square(int copies, int side, double noise, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, noise);
    std::vector<Eigen::Vector3d> points;
    for (int c = 0; c < copies; ++c)
        for (int i = 0; i < side; ++i)
            for (int j = 0; j < side; ++j)
                points.emplace_back(0.001 * i + n(rng), 0.001 * j + n(rng), n(rng));
    return cloud_of(points);
}

/// A filled cube of random points: the voxel count falls as 1 / voxel^3, faster than a
/// surface's, so the first attempt predicted from a surface's law is too late.
PointCloud solid_cube(int count, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 0.2);
    std::vector<Eigen::Vector3d> points;
    for (int i = 0; i < count; ++i) points.emplace_back(u(rng), u(rng), u(rng));
    return cloud_of(points);
}

/// A thin line: the count falls as 1 / voxel, slower than a surface's.
PointCloud line(int count) {
    std::vector<Eigen::Vector3d> points;
    for (int i = 0; i < count; ++i) points.emplace_back(0.0001 * i, 0.0, 0.0);
    return cloud_of(points);
}

// bounded() skips attempts by a prediction; its answer is still the first voxel that fits, on
// surfaces, volumes and lines (counts falling as 1/v^2, 1/v^3, 1/v).
TEST(PointBudget, TheFirstVoxelThatFitsOnAnyShape) {
    struct Case {
        const char* name;
        PointCloud cloud;
        std::size_t max_points;
        double spacing;
    };
    std::vector<Case> cases;
    cases.push_back(
        {"8 overlapping views of a square", overlapping_square(8, 150, 0.0003, 1), 4000, 0.001});
    cases.push_back({"one view of a square", overlapping_square(1, 300, 0.0001, 2), 5000, 0.001});
    cases.push_back({"a solid cube", solid_cube(120000, 3), 3000, 0.00128});
    cases.push_back({"a line", line(100000), 2000, 0.0001});
    cases.push_back({"fits as it is", overlapping_square(1, 50, 0.0001, 4), 5000, 0.001});
    for (const auto& c : cases) {
        double voxel = -1.0;
        const PointCloud down =
            rgbd::reconstruction::internal::bounded(c.cloud, c.max_points, c.spacing, voxel);
        EXPECT_LE(down.size(), c.max_points) << c.name;
        if (c.cloud.size() <= c.max_points) {
            EXPECT_EQ(voxel, 0.0) << c.name;
            EXPECT_EQ(down.size(), c.cloud.size()) << c.name;
            continue;
        }
        EXPECT_EQ(voxel, first_fitting_voxel(c.cloud, c.max_points, c.spacing)) << c.name;
        EXPECT_EQ(down.size(), rgbd::sampling::voxel_downsample(c.cloud, voxel).size()) << c.name;
    }
}

}  // namespace
