#include "algorithms/sampling/voxel_downsample.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <random>

#include "toolkit/error.hpp"

namespace {

using rgbd::PointCloud;

// Clusters of 5 points around the centres of 0.01 m voxels: centre + (±d, 0, 0), (0, ±d, 0), 0.
PointCloud clustered_cloud() {
    PointCloud cloud;
    cloud.view.id = 4;
    cloud.view.sensor = "k2-4";
    cloud.view.grid_width = 512;
    cloud.view.grid_height = 424;
    cloud.points.add_normal_map();
    auto colors = cloud.add_colors();
    auto pixel = cloud.add_pixel_map();
    const double d = 0.002;
    const Eigen::Vector3d offsets[5] = {{d, 0, 0}, {-d, 0, 0}, {0, d, 0}, {0, -d, 0}, {0, 0, 0}};
    std::uint32_t next = 0;
    for (int cz = 0; cz < 2; ++cz)
        for (int cy = 0; cy < 3; ++cy)
            for (int cx = 0; cx < 4; ++cx) {
                const Eigen::Vector3d centre(0.005 + 0.01 * cx, 0.005 + 0.01 * cy,
                                             0.005 + 0.01 * cz);
                for (int k = 0; k < 5; ++k) {
                    auto it = cloud.points.insert(rgbd::to_point(centre + offsets[k]));
                    // Normals tilted +-30 deg in x around +z: the mean is +z.
                    cloud.points.normal(*it) = rgbd::Vector_3(k == 0 ? 0.5 : (k == 1 ? -0.5 : 0.0),
                                                              0.0, k < 2 ? std::sqrt(0.75) : 1.0);
                    colors.set(*it, {static_cast<std::uint8_t>(10 * k), 100,
                                     static_cast<std::uint8_t>(k == 4 ? 255 : 0)});
                    pixel[*it] = next++;
                }
            }
    // Anchor: puts the grid origin at (0, 0, -0.01) so that clusters sit inside voxels.
    auto anchor = cloud.points.insert(rgbd::Point_3(0, 0, -0.01));
    cloud.points.normal(*anchor) = rgbd::Vector_3(0, 0, 1);
    colors.set(*anchor, {20, 100, 51});
    pixel[*anchor] = 9999;
    return cloud;
}

TEST(VoxelDownsample, OnePointPerVoxelWithAveragedAttributes) {
    PointCloud cloud = clustered_cloud();
    const PointCloud out = rgbd::sampling::voxel_downsample(cloud, 0.01);
    ASSERT_EQ(out.size(), 25u);
    EXPECT_EQ(out.view.id, 4);
    EXPECT_EQ(out.view.sensor, "k2-4");
    EXPECT_FALSE(out.view.has_grid());
    ASSERT_TRUE(out.has_colors());
    ASSERT_TRUE(out.points.has_normal_map());
    const auto colors = out.colors();
    const auto pixel = out.pixel_map();
    ASSERT_TRUE(pixel.has_value());
    for (auto idx : out.points) {
        if ((*pixel)[idx] == 9999) continue;  // the anchor
        const Eigen::Vector3d p = rgbd::to_eigen(out.points.point(idx));
        // Centroid = cluster centre (on the 0.005 + 0.01 k lattice).
        for (int a = 0; a < 3; ++a) {
            const double f = (p[a] - 0.005) / 0.01;
            EXPECT_NEAR(f, std::round(f), 1e-9);
        }
        const Eigen::Vector3d n = rgbd::to_eigen(out.points.normal(idx));
        EXPECT_NEAR(n.norm(), 1.0, 1e-12);
        EXPECT_NEAR(n.z(), 1.0, 1e-12);
        EXPECT_EQ(colors.get(idx), (rgbd::Rgb{20, 100, 51}));  // means 20, 100, 51
        // Representative = the centre point (k = 4), nearest to the centroid.
        EXPECT_EQ((*pixel)[idx] % 5, 4u);
    }
}

TEST(VoxelDownsample, DeterministicForAnyThreadCount) {
    PointCloud cloud;
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < 50000; ++i) cloud.points.insert(rgbd::Point_3(u(rng), u(rng), u(rng)));
    PointCloud a, b;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        a = rgbd::sampling::voxel_downsample(cloud, 0.05);
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
        b = rgbd::sampling::voxel_downsample(cloud, 0.05);
    }
    ASSERT_EQ(a.size(), b.size());
    EXPECT_LE(a.size(), 21u * 21u * 21u);
    auto ia = a.points.begin();
    for (auto idx : b.points) EXPECT_EQ(a.points.point(*ia++), b.points.point(idx));
}

TEST(VoxelDownsample, EdgeCases) {
    PointCloud cloud;
    EXPECT_EQ(rgbd::sampling::voxel_downsample(cloud, 0.01).size(), 0u);
    cloud.points.insert(rgbd::Point_3(1, 2, 3));
    cloud.points.insert(rgbd::Point_3(1, 2, 3));  // duplicate
    const PointCloud one = rgbd::sampling::voxel_downsample(cloud, 0.01);
    ASSERT_EQ(one.size(), 1u);
    EXPECT_EQ(one.points.point(*one.points.begin()), rgbd::Point_3(1, 2, 3));
    EXPECT_THROW(rgbd::sampling::voxel_downsample(cloud, 0.0), rgbd::InputError);
    EXPECT_THROW(rgbd::sampling::voxel_downsample(cloud, -1.0), rgbd::InputError);
    cloud.points.insert(rgbd::Point_3(1e6, 0, 0));
    EXPECT_THROW(rgbd::sampling::voxel_downsample(cloud, 1e-6), rgbd::InputError);
}

}  // namespace
