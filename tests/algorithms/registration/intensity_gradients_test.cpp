// internal::compute_intensity_gradients (Park et al.'s tangent-plane intensity gradients, the
// targets of the coloured ICP term): on a gently curved sheet whose intensity rises linearly
// along x, each gradient is the known one in the tangent plane; given the k nearest neighbours
// normals::estimate_normals found (align_views shares them), the gradients are exactly those of
// the kd-tree's own search, and a list shorter than k falls back to the tree.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/pair_icp.hpp"
#include "algorithms/normals/estimate_normals.hpp"
#include "toolkit/point_cloud.hpp"

namespace {

using rgbd::internal::KdTree;
using rgbd::internal::RegCloud;

constexpr double kSlope = 2.0;  // intensity per metre along x

/// A 0.2 m sheet z = 0.05 sin(10 x) at random points, its normals by estimate_normals (the
/// gradient does not depend on their sign), intensity 0.3 + kSlope x; `neighbours` receives
/// the normals' kNN.
RegCloud sheet(std::vector<std::uint32_t>& neighbours) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-0.1, 0.1);
    rgbd::PointCloud cloud;
    for (int i = 0; i < 4000; ++i) {
        const double x = u(rng), y = u(rng);
        cloud.points.insert(rgbd::to_point(Eigen::Vector3d(x, y, 0.05 * std::sin(10.0 * x))));
    }
    rgbd::normals::NormalOptions options;
    options.orientation = rgbd::normals::NormalOrientation::kNone;
    rgbd::normals::estimate_normals(cloud, options, {}, &neighbours);
    RegCloud reg;
    for (auto idx : cloud.points) {
        reg.xyz.push_back(rgbd::to_eigen(cloud.points.point(idx)));
        reg.normals.push_back(rgbd::to_eigen(cloud.points.normal(idx)));
        reg.intensity.push_back(static_cast<float>(0.3 + kSlope * reg.xyz.back().x()));
    }
    return reg;
}

TEST(IntensityGradients, TheKnownSlopeInTheTangentPlane) {
    std::vector<std::uint32_t> neighbours;
    RegCloud reg = sheet(neighbours);
    const KdTree tree(reg.xyz);
    rgbd::internal::compute_intensity_gradients(reg, tree, 16);
    ASSERT_EQ(reg.gradient.size(), reg.xyz.size());
    std::size_t off = 0;
    for (std::size_t i = 0; i < reg.xyz.size(); ++i) {
        const Eigen::Vector3d& n = reg.normals[i];
        const Eigen::Vector3d truth = kSlope * (Eigen::Vector3d::UnitX() - n.x() * n);
        EXPECT_LT(std::abs(reg.gradient[i].dot(n)), 1e-9);
        off += (reg.gradient[i] - truth).norm() > 0.05 * kSlope;
    }
    EXPECT_LT(off, reg.xyz.size() / 50) << off << " gradients more than 5% off";
}

TEST(IntensityGradients, TheNormalsNeighboursGiveTheTreesGradients) {
    std::vector<std::uint32_t> neighbours;
    RegCloud a = sheet(neighbours);
    ASSERT_EQ(neighbours.size(), a.xyz.size() * 24u) << "the kd-tree path lists k = 24 a point";
    const KdTree tree(a.xyz);
    // The list: every point's 24 nearest, nearest first, the point itself first.
    std::vector<std::uint32_t> nn(24);
    std::vector<double> sq(24);
    for (std::size_t i = 0; i < a.xyz.size(); i += 97) {
        ASSERT_EQ(tree.knn(a.xyz[i], 24, nn.data(), sq.data()), 24u);
        for (std::size_t j = 0; j < 24; ++j) EXPECT_EQ(neighbours[i * 24 + j], nn[j]) << i;
    }
    RegCloud b = a, c = a;
    rgbd::internal::compute_intensity_gradients(a, tree, 16);
    rgbd::internal::compute_intensity_gradients(b, tree, 16, neighbours);
    // Eight a point: fewer than the 16 asked, so the tree answers.
    std::vector<std::uint32_t> short_list;
    for (std::size_t i = 0; i < c.xyz.size(); ++i)
        short_list.insert(short_list.end(), neighbours.begin() + i * 24,
                          neighbours.begin() + i * 24 + 8);
    rgbd::internal::compute_intensity_gradients(c, tree, 16, short_list);
    for (std::size_t i = 0; i < a.xyz.size(); ++i) {
        ASSERT_EQ(a.gradient[i], b.gradient[i]) << "point " << i;
        ASSERT_EQ(a.gradient[i], c.gradient[i]) << "point " << i;
    }
}

}  // namespace
