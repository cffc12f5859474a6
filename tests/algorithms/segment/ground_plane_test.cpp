// detail::pooled_bounding_plane (algorithms/segment/ground_plane.hpp), the RANSAC behind the
// wall search: a sample votes for a plane only when it lies within half a band of it AND faces
// it. A thin slab of points whose normals lie along the slab (a slice through a body, not a
// surface) outnumbers a real plane of points facing it; the real plane must win, with exactly
// its points as inliers.
#include "algorithms/segment/ground_plane.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace {

using rgbd::segment::detail::GroundSample;

TEST(PooledBoundingPlane, VotesNeedTheSamplesToFaceThePlane) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0), up(0.1, 1.0), thin(-0.01, 0.01);
    std::vector<GroundSample> samples;
    // The plane z = 0, its points facing it (normal +z): 2000.
    for (int i = 0; i < 2000; ++i)
        samples.push_back({Eigen::Vector3d(u(rng), u(rng), 0.0), Eigen::Vector3d::UnitZ()});
    // A slab 2 cm thick about x = 0 above it, 4001 points (an odd count: the vector loop's
    // scalar tail runs too), normals along +z: within the band of x = 0 but facing away.
    for (int i = 0; i < 4001; ++i)
        samples.push_back({Eigen::Vector3d(thin(rng), u(rng), up(rng)), Eigen::Vector3d::UnitZ()});
    std::vector<std::uint8_t> used(samples.size(), 0);
    rgbd::segment::SubjectOptions options;
    std::size_t inliers = 0, behind = 0;
    const auto plane = rgbd::segment::detail::pooled_bounding_plane(
        samples, used, Eigen::Vector3d(0.5, 0.3, 2.0), options, 11, inliers, behind);
    ASSERT_TRUE(plane.has_value());
    EXPECT_GT(plane->n.z(), std::cos(1.0 * M_PI / 180.0)) << plane->n.transpose();
    EXPECT_LT(std::abs(plane->d), 1e-9);
    EXPECT_EQ(inliers, 2000u);
    for (std::size_t i = 0; i < samples.size(); ++i) EXPECT_EQ(used[i], i < 2000 ? 1 : 0) << i;
}

}  // namespace
