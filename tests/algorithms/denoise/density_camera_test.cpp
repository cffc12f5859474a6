// Tests of the density filter's per-camera visibility (algorithms/denoise/density_camera.hpp):
// surely_occluded(), which lets the filter leave a camera out of a whole counting cell, must
// never drop a camera that camera_density() would count for some point of the cell.
#include "algorithms/denoise/density_camera.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>
#include <tuple>
#include <utility>

#include "tests/support/pinhole.hpp"

namespace rgbd::denoise::detail {
namespace {

constexpr int kW = 160, kH = 120;

/// A camera at `centre` turned by `turn`, whose depth map (over the pixel box [20, 140) x
/// [10, 110)) holds a noisy surface at `wall_m` with a hole of missing returns and a nearer step.
Camera camera(const Eigen::Vector3d& centre, const Eigen::Matrix3d& turn, double wall_m,
              std::mt19937_64& rng) {
    Camera c;
    Pose world_from_sensor = Pose::Identity();
    world_from_sensor.linear() = turn;
    world_from_sensor.translation() = centre;
    c.set(world_from_sensor, test::centred_pinhole(kW, kH, 140.0));
    c.active = true;
    c.x0 = 20, c.y0 = 10, c.bw = 120, c.bh = 100;
    c.depth.assign(std::size_t(c.bw) * c.bh, 0.0f);
    std::normal_distribution<double> noise(0.0, 0.002);
    for (int r = 0; r < c.bh; ++r)
        for (int col = 0; col < c.bw; ++col) {
            double d = wall_m + noise(rng);
            if (col > 70 && r > 60) d -= 0.25;  // a nearer step
            if (col > 30 && col < 45 && r > 20 && r < 40)
                d = std::numeric_limits<double>::infinity();  // a hole: no returns
            c.depth[std::size_t(r) * c.bw + col] = float(d);
        }
    return c;
}

TEST(DensityCamera, SurelyOccludedBoxesGetNoDensityAnywhere) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const auto random_unit = [&] {
        Eigen::Vector3d d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5);
        return Eigen::Vector3d(d.normalized());
    };
    std::size_t occluded_boxes = 0, other_boxes = 0, points_checked = 0;
    for (int trial = 0; trial < 40; ++trial) {
        const Eigen::Matrix3d turn =
            Eigen::AngleAxisd(0.3 * (unit(rng) - 0.5), random_unit()).toRotationMatrix();
        const Eigen::Vector3d centre(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5);
        const double wall = 1.0 + 2.0 * unit(rng);
        const Camera c = camera(centre, turn, wall, rng);
        const Pose world_from_sensor = c.sensor_from_world.inverse();
        for (const NoiseModel model : {NoiseModel::kKinectV2, NoiseModel::kSr300}) {
            const double tan_max = std::tan(80.0 * M_PI / 180.0);
            for (int b = 0; b < 300; ++b) {
                // A box around a point of the view (in front of, on or behind the surface).
                const double u = 25 + 110 * unit(rng), v = 15 + 90 * unit(rng);
                const double z = wall * (0.6 + 0.8 * unit(rng));
                const Eigen::Vector3d p = world_from_sensor * c.intrinsics.unproject(u, v, z);
                const Eigen::Vector3d half =
                    Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * (0.002 + 0.03 * unit(rng));
                const Eigen::Vector3d lo = p - half, hi = p + half;
                if (!surely_occluded(c, lo, hi, model, tan_max)) {
                    ++other_boxes;
                    continue;
                }
                ++occluded_boxes;
                // Its corners and points inside: camera_density() counts none of them.
                for (int s = 0; s < 64; ++s) {
                    Eigen::Vector3d q;
                    for (int a = 0; a < 3; ++a)
                        q(a) = s < 8 ? ((s >> a) & 1 ? hi(a) : lo(a))
                                     : lo(a) + (hi(a) - lo(a)) * unit(rng);
                    EXPECT_FALSE(camera_density(c, q, random_unit(), model, tan_max).has_value())
                        << "box " << b << " of trial " << trial << ", sample " << s;
                    ++points_checked;
                }
            }
        }
    }
    // Both answers occur, so the property above was put to the test.
    EXPECT_GT(occluded_boxes, 1000u);
    EXPECT_GT(other_boxes, 1000u);
    EXPECT_EQ(points_checked, 64 * occluded_boxes);
}

TEST(DensityCamera, UnsureCasesAreNotOccluded) {
    std::mt19937_64 rng(3);
    const Camera c = camera(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(), 2.0, rng);
    const double tan_max = std::tan(80.0 * M_PI / 180.0);
    const auto box = [](const Eigen::Vector3d& p, double h) {
        const Eigen::Vector3d d = Eigen::Vector3d::Constant(h);
        return std::pair<Eigen::Vector3d, Eigen::Vector3d>(p - d, p + d);
    };
    // Far behind the surface, inside the map: occluded.
    auto [lo, hi] = box(c.intrinsics.unproject(50, 80, 3.0), 0.005);
    EXPECT_TRUE(surely_occluded(c, lo, hi, NoiseModel::kKinectV2, tan_max));
    // On the surface; behind the hole; outside the map's box; behind the camera: not sure.
    std::tie(lo, hi) = box(c.intrinsics.unproject(50, 80, 2.0), 0.005);
    EXPECT_FALSE(surely_occluded(c, lo, hi, NoiseModel::kKinectV2, tan_max));
    std::tie(lo, hi) = box(c.intrinsics.unproject(57, 40, 3.0), 0.005);
    EXPECT_FALSE(surely_occluded(c, lo, hi, NoiseModel::kKinectV2, tan_max));
    std::tie(lo, hi) = box(c.intrinsics.unproject(5, 5, 3.0), 0.005);
    EXPECT_FALSE(surely_occluded(c, lo, hi, NoiseModel::kKinectV2, tan_max));
    std::tie(lo, hi) = box(Eigen::Vector3d(0, 0, -1.0), 0.005);
    EXPECT_FALSE(surely_occluded(c, lo, hi, NoiseModel::kKinectV2, tan_max));
    // A distorted lens: never sure.
    Camera distorted = c;
    distorted.undistorted = false;
    std::tie(lo, hi) = box(c.intrinsics.unproject(50, 80, 3.0), 0.005);
    EXPECT_FALSE(surely_occluded(distorted, lo, hi, NoiseModel::kKinectV2, tan_max));
}

TEST(DensityCamera, DensityIsIncidenceCosineOverSampleSpacingSquared) {
    // A camera turned and moved away from the origin, looking at its own wall: a point on the
    // wall gets cos(theta) / (z / focal)^2 for any normal, with theta between the normal and
    // the ray from the camera's centre; a point behind the wall or behind the camera gets none.
    std::mt19937_64 rng(5);
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    const Eigen::Vector3d centre(0.3, -0.2, 1.1);
    const Camera c = camera(centre, turn, 2.0, rng);
    const double tan_max = std::tan(80.0 * M_PI / 180.0);
    std::size_t checked = 0;
    for (int i = 0; i < 200; ++i) {
        // Pixels of the wall away from its hole and its step.
        const double col = std::uniform_real_distribution<double>(25, 48)(rng);
        const double row = std::uniform_real_distribution<double>(52, 68)(rng);
        const Eigen::Vector3d in_camera = c.intrinsics.unproject(col, row, 2.0);
        const Eigen::Vector3d p = turn * in_camera + centre;
        std::normal_distribution<double> gauss;
        const Eigen::Vector3d n = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
        const auto got = camera_density(c, p, n, NoiseModel::kKinectV2, tan_max);
        ASSERT_TRUE(got.has_value()) << "pixel " << col << ", " << row;
        const double cos_theta = std::abs(n.dot((p - centre).normalized()));
        const double s_d = in_camera.z() / 140.0;
        EXPECT_NEAR(*got, cos_theta / (s_d * s_d), 1e-9 * (1.0 / (s_d * s_d)));
        const Eigen::Vector3d behind = turn * c.intrinsics.unproject(col, row, 2.5) + centre;
        EXPECT_FALSE(camera_density(c, behind, n, NoiseModel::kKinectV2, tan_max).has_value());
        const Eigen::Vector3d at_back = centre - turn * Eigen::Vector3d(0, 0, 1.0);
        EXPECT_FALSE(camera_density(c, at_back, n, NoiseModel::kKinectV2, tan_max).has_value());
        ++checked;
    }
    EXPECT_EQ(checked, 200u);
}

}  // namespace
}  // namespace rgbd::denoise::detail
