// Tests of upsample_view (docs/algorithms.md §5) on synthetic frames with known answers: a tilted
// plane (new points on the plane, exact colour pixels), a step edge (nothing in the gap),
// counts for 4 and 8 neighbours, flags and confidence, the midpoint variant, errors, and
// determinism for 1 and 2 threads.
#include "algorithms/upsample/upsample_view.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <functional>

#include "algorithms/frames/depth_to_cloud.hpp"
#include "toolkit/error.hpp"

namespace rgbd::upsample {
namespace {

constexpr int kW = 96, kH = 72;

/// Colour of a colour pixel: a 1-pixel pattern, so every colour pixel differs from its
/// neighbours and a wrong pixel would be caught.
cv::Vec3b pattern(int u, int v) {
    return {static_cast<std::uint8_t>((u * 37 + v * 11) % 256),
            static_cast<std::uint8_t>((u * 5 + v * 53) % 256),
            static_cast<std::uint8_t>((u ^ v) % 256)};
}

/// A Kinect-v2-like frame: colour focal length 2.96x the depth's, 52 mm baseline, the depth
/// given as a function of the depth ray (the surface: a depth along the ray per pixel).
RgbdFrame make_frame(const std::function<double(const Eigen::Vector3d&)>& depth_along_ray) {
    RgbdFrame f;
    f.depth_intrinsics.width = kW;
    f.depth_intrinsics.height = kH;
    f.depth_intrinsics.fx = f.depth_intrinsics.fy = 70.0;
    f.depth_intrinsics.cx = (kW - 1) / 2.0;
    f.depth_intrinsics.cy = (kH - 1) / 2.0;
    f.color_intrinsics.width = 3 * kW + 40;
    f.color_intrinsics.height = 3 * kH + 30;
    f.color_intrinsics.fx = f.color_intrinsics.fy = 70.0 * 2.96;
    f.color_intrinsics.cx = (f.color_intrinsics.width - 1) / 2.0;
    f.color_intrinsics.cy = (f.color_intrinsics.height - 1) / 2.0;
    f.color_from_depth = Pose::Identity();
    f.color_from_depth.translation() = Eigen::Vector3d(-0.052, 0.0, 0.0);
    f.depth = cv::Mat(kH, kW, CV_32FC1);
    for (int v = 0; v < kH; ++v)
        for (int u = 0; u < kW; ++u) {
            const Eigen::Vector3d ray = f.depth_intrinsics.unproject(u, v, 1.0);
            f.depth.at<float>(v, u) = static_cast<float>(depth_along_ray(ray));
        }
    f.color = cv::Mat(f.color_intrinsics.height, f.color_intrinsics.width, CV_8UC3);
    for (int v = 0; v < f.color.rows; ++v)
        for (int u = 0; u < f.color.cols; ++u) f.color.at<cv::Vec3b>(v, u) = pattern(u, v);
    f.sensor_id = "k0";
    f.source = "synthetic";
    return f;
}

/// Tilted plane n.X = d, about 1.5 m away.
const Eigen::Vector3d kNormal = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
const double kD = kNormal.dot(Eigen::Vector3d(0, 0, 1.5));

RgbdFrame plane_frame() {
    return make_frame([](const Eigen::Vector3d& ray) { return kD / kNormal.dot(ray); });
}

PointCloud cloud_of(const RgbdFrame& frame) {
    frames::CloudOptions options;
    options.visibility_test = false;
    return frames::depth_to_cloud(frame, options);
}

TEST(UpsampleView, TiltedPlaneNewPointsOnPlaneWithExactColourPixels) {
    const RgbdFrame frame = plane_frame();
    PointCloud cloud = cloud_of(frame);
    const std::size_t n = cloud.size();
    UpsampleOptions options;
    const Report report = upsample_view(cloud, frame, options);
    ASSERT_GT(cloud.size(), n);
    const auto synthetic = cloud.flag(prop::kSynthetic);
    const auto confidence = cloud.float_map(prop::kConfidence);
    ASSERT_TRUE(synthetic && confidence);
    const auto colors = cloud.colors();
    const PinholeIntrinsics& kc = frame.color_intrinsics;
    double worst = 0.0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        const PointSet::Index idx(i);
        EXPECT_EQ((*synthetic)[idx], i >= n ? 1 : 0);
        if (i < n) continue;
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        worst = std::max(worst, std::abs(kNormal.dot(p) - kD));
        const Eigen::Vector2d q = kc.project(frame.color_from_depth * p);
        const int u = static_cast<int>(std::lround(q.x())),
                  v = static_cast<int>(std::lround(q.y()));
        EXPECT_NEAR(q.x(), u, 1e-6);
        EXPECT_NEAR(q.y(), v, 1e-6);
        const cv::Vec3b c = pattern(u, v);
        EXPECT_EQ(colors.get(idx), (Rgb{c[2], c[1], c[0]}));
        EXPECT_GT((*confidence)[idx], 0.0f);
        EXPECT_LE((*confidence)[idx], 1.0f);
    }
    EXPECT_LT(worst, 1e-6) << "new points must lie on the plane (noise off)";
    EXPECT_GE(static_cast<double>(cloud.size()) / n, 7.5) << report.dump();
}

TEST(UpsampleView, FourNeighboursCount) {
    const RgbdFrame frame = plane_frame();
    PointCloud cloud = cloud_of(frame);
    const std::size_t n = cloud.size();
    UpsampleOptions options;
    options.neighbors = 4;
    upsample_view(cloud, frame, options);
    const double ratio = static_cast<double>(cloud.size()) / n;
    EXPECT_GE(ratio, 4.2);
    EXPECT_LE(ratio, 5.0);
}

TEST(UpsampleView, EightNeighboursAtMostNine) {
    const RgbdFrame frame = plane_frame();
    PointCloud cloud = cloud_of(frame);
    const std::size_t n = cloud.size();
    upsample_view(cloud, frame, UpsampleOptions{});
    EXPECT_LE(static_cast<double>(cloud.size()) / n, 9.0);
}

TEST(UpsampleView, StepEdgeLeavesTheGapEmpty) {
    // Left half at 1.4 m, right half at 1.6 m (fronto-parallel planes).
    const RgbdFrame frame =
        make_frame([](const Eigen::Vector3d& ray) { return ray.x() < 0.0 ? 1.4 : 1.6; });
    PointCloud cloud = cloud_of(frame);
    const std::size_t n = cloud.size();
    const Report report = upsample_view(cloud, frame, UpsampleOptions{});
    EXPECT_GT(report["gated_discontinuity"].get<std::size_t>(), 0u);
    std::size_t in_gap = 0;
    for (std::size_t i = n; i < cloud.size(); ++i) {
        const double z = cloud.points.point(PointSet::Index(i)).z();
        in_gap += std::abs(z - 1.4) > 1e-6 && std::abs(z - 1.6) > 1e-6;
    }
    EXPECT_EQ(in_gap, 0u);
    EXPECT_GE(static_cast<double>(cloud.size()) / n, 7.0);
}

TEST(UpsampleView, MidpointsOnThePlane) {
    const RgbdFrame frame = plane_frame();
    for (int k : {4, 8}) {
        PointCloud cloud = cloud_of(frame);
        const std::size_t n = cloud.size();
        UpsampleOptions options;
        options.method = UpsampleMethod::kMidpoints;
        options.neighbors = k;
        upsample_view(cloud, frame, options);
        const double ratio = static_cast<double>(cloud.size()) / n;
        EXPECT_GE(ratio, k == 4 ? 2.8 : 4.6);
        EXPECT_LE(ratio, k == 4 ? 3.0 : 5.0);
        for (std::size_t i = n; i < cloud.size(); ++i)
            EXPECT_NEAR(kNormal.dot(to_eigen(cloud.points.point(PointSet::Index(i)))), kD, 1e-6);
    }
}

TEST(UpsampleView, WorldFrameViewStaysInWorldFrame) {
    const RgbdFrame frame = plane_frame();
    PointCloud sensor = cloud_of(frame);
    PointCloud world = sensor;
    Pose pose = Pose::Identity();
    pose.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1, 0).normalized()).matrix();
    pose.translation() = Eigen::Vector3d(0.3, -1, 2);
    world.view.world_from_sensor = pose;
    to_world_frame(world);
    upsample_view(sensor, frame, UpsampleOptions{});
    upsample_view(world, frame, UpsampleOptions{});
    ASSERT_EQ(sensor.size(), world.size());
    for (std::size_t i = 0; i < sensor.size(); i += 97) {
        const PointSet::Index idx(i);
        EXPECT_LT(
            (pose * to_eigen(sensor.points.point(idx)) - to_eigen(world.points.point(idx))).norm(),
            1e-9);
    }
}

TEST(UpsampleView, DeterministicForOneAndTwoThreads) {
    const RgbdFrame frame = make_frame([](const Eigen::Vector3d& ray) {
        return 1.5 + 0.05 * std::sin(20 * ray.x()) * std::cos(15 * ray.y());
    });
    auto run = [&](int threads) {
        tbb::global_control control(tbb::global_control::max_allowed_parallelism, threads);
        PointCloud cloud = cloud_of(frame);
        upsample_view(cloud, frame, UpsampleOptions{});
        return cloud;
    };
    const PointCloud a = run(1), b = run(2);
    ASSERT_EQ(a.size(), b.size());
    const auto ca = a.colors(), cb = b.colors();
    for (std::size_t i = 0; i < a.size(); ++i) {
        const PointSet::Index idx(i);
        ASSERT_EQ(a.points.point(idx), b.points.point(idx));
        ASSERT_EQ(ca.get(idx), cb.get(idx));
    }
}

TEST(UpsampleView, Errors) {
    const RgbdFrame frame = plane_frame();
    PointCloud cloud = cloud_of(frame);
    PointCloud no_grid = cloud;
    no_grid.view.grid_width = no_grid.view.grid_height = 0;
    EXPECT_THROW(upsample_view(no_grid, frame, UpsampleOptions{}), InputError);
    RgbdFrame no_colour = frame;
    no_colour.color = cv::Mat();
    EXPECT_THROW(upsample_view(cloud, no_colour, UpsampleOptions{}), InputError);
    RgbdFrame small = frame;
    small.color = cv::Mat(10, 10, CV_8UC3);
    EXPECT_THROW(upsample_view(cloud, small, UpsampleOptions{}), InputError);
    UpsampleOptions bad;
    bad.neighbors = 6;
    EXPECT_THROW(bad.check(), InputError);
    PointCloud empty;
    empty.view = cloud.view;
    empty.add_pixel_map();
    const Report r = upsample_view(empty, frame, UpsampleOptions{});
    EXPECT_EQ(r["added"].get<std::size_t>(), 0u);
}

}  // namespace
}  // namespace rgbd::upsample
