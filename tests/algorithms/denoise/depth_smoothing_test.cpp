// Tests of the edge-aware depth smoothing (depth_smoothing.hpp) on synthetic organised views
// with known surfaces: a noisy tilted plane gets closer to the truth, points stay on their
// rays, a depth step keeps its two sides apart, flagged points are neither moved nor used,
// world-frame views, errors.
#include "algorithms/denoise/depth_smoothing.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "tests/support/input_error.hpp"
#include "tests/support/pinhole.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {
namespace {

using rgbd::test::expect_input_error;

constexpr int kW = 120, kH = 100;
constexpr double kF = 365.5;

PinholeIntrinsics intrinsics() { return test::centred_pinhole(kW, kH, kF); }

/// Organised view of a depth function (NaN = no return) with Gaussian noise of the Kinect v2
/// model; `truth` gets the noise-free depth of every point in insertion order.
PointCloud view_of(double (*depth)(int, int), std::vector<double>& truth, std::uint64_t seed) {
    PointCloud cloud;
    cloud.view.id = 7;
    cloud.view.grid_width = kW;
    cloud.view.grid_height = kH;
    cloud.view.intrinsics = intrinsics();
    auto pixel = cloud.add_pixel_map();
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> unit(0.0, 1.0);
    const auto k = intrinsics();
    for (int row = 0; row < kH; ++row)
        for (int col = 0; col < kW; ++col) {
            const double z = depth(col, row);
            if (!std::isfinite(z)) continue;
            const double noisy = z + sigma_z_m(NoiseModel::kKinectV2, z) * unit(rng);
            auto idx = *cloud.points.insert(to_point(k.unproject(col, row, noisy)));
            pixel[idx] = std::uint32_t(row * kW + col);
            truth.push_back(z);
        }
    return cloud;
}

/// A plane tilted 50 degrees about the vertical axis through (0, 0, 1.5 m): 1/z is affine.
double tilted(int col, int) {
    const double x = (col - kW / 2.0) / kF;  // x / z of the ray
    const double t = std::tan(50.0 * std::numbers::pi / 180.0);
    return 1.5 / (1.0 - t * x);  // z = 1.5 + t X, X = x z
}

/// Left half at 1.2 m, right half at 1.26 m (a 60 mm step: 20 sigma of the noise).
double step(int col, int) { return col < kW / 2 ? 1.2 : 1.26; }

std::vector<double> depths(const PointCloud& cloud) {
    std::vector<double> z;
    for (auto idx : cloud.points) z.push_back(cloud.points.point(idx).z());
    return z;
}

double rms_error(const std::vector<double>& z, const std::vector<double>& truth) {
    double s = 0.0;
    for (std::size_t i = 0; i < z.size(); ++i) s += (z[i] - truth[i]) * (z[i] - truth[i]);
    return std::sqrt(s / double(z.size()));
}

TEST(DepthSmoothing, TiltedPlaneGetsCloserToTheTruthAlongItsRays) {
    std::vector<double> truth;
    PointCloud cloud = view_of(&tilted, truth, 1);
    std::vector<Eigen::Vector3d> before;
    for (auto idx : cloud.points) before.push_back(to_eigen(cloud.points.point(idx)));
    const double error_before = rms_error(depths(cloud), truth);
    const Report report = smooth_depth(cloud, SmoothOptions{});
    const double error_after = rms_error(depths(cloud), truth);
    // 25 pixels and 3 parameters: the fitted depth's error is about sqrt(3 / 25) of one pixel's.
    EXPECT_LT(error_after, 0.5 * error_before) << error_before << " -> " << error_after;
    EXPECT_GT(report["moved"].get<std::size_t>(), cloud.size() * 9 / 10);
    std::size_t i = 0;
    for (auto idx : cloud.points) {  // each point stays on its own ray
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        EXPECT_NEAR(p.x() / p.z(), before[i].x() / before[i].z(), 1e-9);
        EXPECT_NEAR(p.y() / p.z(), before[i].y() / before[i].z(), 1e-9);
        ++i;
    }
}

TEST(DepthSmoothing, AStepKeepsItsTwoSidesApart) {
    std::vector<double> truth;
    PointCloud cloud = view_of(&step, truth, 2);
    const double error_before = rms_error(depths(cloud), truth);
    smooth_depth(cloud, SmoothOptions{});
    const std::vector<double> z = depths(cloud);
    EXPECT_LT(rms_error(z, truth), 0.6 * error_before);
    // No point drifts towards the other side: every point stays within 4 sigma of its own
    // surface (a box filter across the step would pull the edge columns 12-24 mm over).
    for (std::size_t i = 0; i < z.size(); ++i)
        EXPECT_LT(std::abs(z[i] - truth[i]), 4.0 * sigma_z_m(NoiseModel::kKinectV2, truth[i]))
            << "point " << i;
}

TEST(DepthSmoothing, FlaggedPointsAreNeitherMovedNorUsed) {
    std::vector<double> truth;
    PointCloud cloud = view_of(&step, truth, 3);
    // Flag every point of the left half but one column: that column has too little support
    // from unflagged pixels of its own surface to move (its window's other columns are
    // flagged or the other surface), and the flagged points stay exactly where they were.
    auto noise = cloud.add_flag(prop::kNoise);
    auto pixel = *cloud.pixel_map();
    std::vector<Eigen::Vector3d> before;
    for (auto idx : cloud.points) {
        before.push_back(to_eigen(cloud.points.point(idx)));
        const int col = int(pixel[idx] % kW);
        if (col < kW / 2 && col != 20) noise[idx] = 1;
    }
    const Report report = smooth_depth(cloud, SmoothOptions{});
    std::size_t i = 0;
    for (auto idx : cloud.points) {
        const int col = int(pixel[idx] % kW);
        if (col < kW / 2) {
            EXPECT_EQ(to_eigen(cloud.points.point(idx)), before[i]) << i;
        }
        ++i;
    }
    EXPECT_GT(report["moved"].get<std::size_t>(), 0u);  // the right half moved
}

TEST(DepthSmoothing, WorldFrameViewMovesLikeItsSensorFrameTwin) {
    std::vector<double> truth;
    PointCloud sensor = view_of(&tilted, truth, 4);
    PointCloud world = sensor;
    Pose pose = Pose::Identity();
    pose.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).matrix();
    pose.translation() = Eigen::Vector3d(0.4, -1.1, 2.0);
    world.view.frame = ViewFrame::kWorld;
    world.view.world_from_sensor = pose;
    for (auto idx : world.points)
        world.points.point(idx) = to_point(pose * to_eigen(world.points.point(idx)));
    smooth_depth(sensor, SmoothOptions{});
    smooth_depth(world, SmoothOptions{});
    auto a = sensor.points.begin();
    for (auto idx : world.points) {
        EXPECT_LT(
            (pose.inverse() * to_eigen(world.points.point(idx)) - to_eigen(sensor.points.point(*a)))
                .norm(),
            1e-6);
        ++a;
    }
}

TEST(DepthSmoothing, ErrorsNameTheViewAndOptionsAreChecked) {
    std::vector<double> truth;
    PointCloud cloud = view_of(&tilted, truth, 5);
    PointCloud no_grid = cloud;
    no_grid.view.grid_width = no_grid.view.grid_height = 0;
    expect_input_error([&] { smooth_depth(no_grid, SmoothOptions{}); }, {"view 7", "organised"});
    PointCloud nan = cloud;
    nan.points.point(*nan.points.begin()) = to_point(Eigen::Vector3d(0.0, std::nan(""), 1.0));
    EXPECT_THROW(smooth_depth(nan, SmoothOptions{}), InputError);
    PointCloud world = cloud;
    world.view.frame = ViewFrame::kWorld;  // no pose
    EXPECT_THROW(smooth_depth(world, SmoothOptions{}), InputError);
    for (const auto& bad :
         {SmoothOptions{.half_window = 0}, SmoothOptions{.half_window = 8},
          SmoothOptions{.gate_sigmas = 0.0}, SmoothOptions{.gate_sigmas = std::nan("")},
          SmoothOptions{.min_support = 26}})
        EXPECT_THROW(bad.check(), InputError);
    PointCloud empty;
    EXPECT_EQ(smooth_depth(empty, SmoothOptions{})["moved"].get<std::size_t>(), 0u);
}

}  // namespace
}  // namespace rgbd::denoise
