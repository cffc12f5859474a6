// Tests of the adaptive distance-based filter (docs/algorithms.md §4) on synthetic organised
// frames with known answers: flying pixels between a foreground and a background, speckles,
// a plane tilted 70 degrees, the same scene at 1 m and 3 m, mark == delete, errors, threads.
#include "algorithms/denoise/distance_outliers.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "tests/support/input_error.hpp"
#include "tests/support/options_check.hpp"
#include "tests/support/pinhole.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {
namespace {

using test::expect_input_error;
using test::rejects;

constexpr int kW = 160, kH = 120;
constexpr double kF = 365.5;

/// Depth function of a synthetic scene; NaN = no return. `truth` gets 1 for surface pixels.
struct Frame {
    PointCloud cloud;
    std::set<std::uint32_t> noise;  ///< pixels that are noise by construction
    std::size_t surface = 0;
};

PinholeIntrinsics intrinsics() { return test::centred_pinhole(kW, kH, kF); }

/// Adds pixel (col, row) at depth z to the frame.
void add(Frame& f, int col, int row, double z, bool noise) {
    const auto k = intrinsics();
    auto pixel = f.cloud.add_pixel_map();
    const Eigen::Vector3d p = k.unproject(col, row, z);
    auto idx = *f.cloud.points.insert(to_point(p));
    const std::uint32_t px = std::uint32_t(row * kW + col);
    pixel[idx] = px;
    if (noise)
        f.noise.insert(px);
    else
        ++f.surface;
}

Frame empty_frame() {
    Frame f;
    f.cloud.view.id = 3;
    f.cloud.view.sensor = "k2-3";
    f.cloud.view.grid_width = kW;
    f.cloud.view.grid_height = kH;
    f.cloud.view.intrinsics = intrinsics();
    f.cloud.add_pixel_map();
    return f;
}

/// A fronto-parallel square object at depth z (noise sigma_z) with flying pixels on its left
/// and right silhouettes (blends towards a far background), isolated speckles and outliers.
Frame object_scene(double z, std::uint64_t seed = 1) {
    Frame f = empty_frame();
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0.0, sigma_z_m(NoiseModel::kKinectV2, z));
    std::uniform_real_distribution<double> blend(0.1, 0.9);
    const double background = 4.5;
    for (int row = 20; row < 100; ++row) {
        for (int col = 40; col < 120; ++col) add(f, col, row, z + noise(rng), false);
        // Flying pixels just outside the silhouette, between object and background.
        for (int col : {38, 39, 120, 121}) {
            if (rng() % 2) continue;
            const double t = blend(rng);
            add(f, col, row, z + t * (background - z), true);
        }
    }
    // Speckles: 3 x 3 clumps floating 0.3 m in front of the object.
    for (int s = 0; s < 4; ++s)
        for (int dr = 0; dr < 3; ++dr)
            for (int dc = 0; dc < 3; ++dc) add(f, 5 + 30 * s + dc, 5 + dr, z - 0.3, true);
    // Isolated outliers anywhere in the free area below the object.
    for (int o = 0; o < 20; ++o) add(f, 5 + 7 * o, 110, 0.6 + 0.15 * o, true);
    return f;
}

struct Score {
    double recall = 0, inlier_loss = 0;
};

Score score(const Frame& before, const PointCloud& after) {
    std::set<std::uint32_t> kept;
    const auto pixel = *after.pixel_map();
    for (auto idx : after.points) kept.insert(pixel[idx]);
    std::size_t noise_removed = 0, surface_removed = 0;
    const auto pb = *before.cloud.pixel_map();
    for (auto idx : before.cloud.points) {
        const std::uint32_t px = pb[idx];
        const bool removed = !kept.count(px);
        if (before.noise.count(px))
            noise_removed += removed;
        else
            surface_removed += removed;
    }
    return {double(noise_removed) / double(before.noise.size()),
            double(surface_removed) / double(before.surface)};
}

TEST(DistanceOutliers, RemovesFlyingPixelsSpecklesAndOutliers) {
    Frame f = object_scene(1.5);
    PointCloud cloud = f.cloud;
    const Report r = remove_distance_outliers(cloud, DistanceOptions{});
    const Score s = score(f, cloud);
    EXPECT_GE(s.recall, 0.99) << r.dump();
    EXPECT_LE(s.inlier_loss, 0.02) << r.dump();
    EXPECT_GT(r["flying"].get<int>(), 0);
    EXPECT_GT(r["speckle"].get<int>(), 0);
}

/// A plane through (0, 0, 1.5) whose normal is tilted by `tilt_deg` about the y axis: each
/// pixel's depth from its ray-plane intersection plus the Kinect v2 axial noise at that depth
/// and incidence; pixels outside [z_min, z_max] and a share `dropout` of the others stay empty.
Frame tilted_plane(double tilt_deg, double z_min, double z_max, double dropout,
                   std::uint64_t seed) {
    Frame f = empty_frame();
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    const double tilt = tilt_deg * std::numbers::pi / 180.0;
    const Eigen::Vector3d normal(std::sin(tilt), 0.0, -std::cos(tilt));
    const Eigen::Vector3d origin(0.0, 0.0, 1.5);
    const auto k = intrinsics();
    for (int row = 0; row < kH; ++row)
        for (int col = 0; col < kW; ++col) {
            const Eigen::Vector3d ray = k.unproject(col, row, 1.0);  // z = 1: t is the depth
            const double z = normal.dot(origin) / normal.dot(ray);
            if (z < z_min || z > z_max || (dropout > 0 && uniform(rng) < dropout)) continue;
            const double theta = std::acos(std::abs(normal.dot(ray.normalized())));
            std::normal_distribution<double> noise(0.0, sigma_z_m(NoiseModel::kKinectV2, z, theta));
            add(f, col, row, z + noise(rng), false);
        }
    return f;
}

TEST(DistanceOutliers, KeepsAPlaneTiltedSeventyDegrees) {
    const Frame f = tilted_plane(70.0, 0.5, 4.5, 0.0, 5);
    PointCloud cloud = f.cloud;
    const Report r = remove_distance_outliers(cloud, DistanceOptions{});
    const double loss = 1.0 - double(cloud.size()) / double(f.surface);
    EXPECT_LE(loss, 0.02) << r.dump();
}

// Spikes inside a dense surface: single pixels 20-35 mm off a wall that fills the frame
// (multipath-like). Their 5 x 5 window still holds surface points within the support radius
// (the window test keeps them); no grid line passes through them (the line test removes them).
TEST(DistanceOutliers, LineTestRemovesSpikesInsideDenseSurface) {
    Frame f = empty_frame();
    std::mt19937_64 rng(11);
    const double wall = 1.5;
    std::normal_distribution<double> noise(0.0, sigma_z_m(NoiseModel::kKinectV2, wall));
    std::uniform_real_distribution<double> offset(0.020, 0.035);
    for (int row = 0; row < kH; ++row)
        for (int col = 0; col < kW; ++col) {
            const bool spike = row % 10 == 5 && col % 10 == 5;
            if (spike)
                add(f, col, row, wall + (rng() % 2 ? 1 : -1) * offset(rng), true);
            else
                add(f, col, row, wall + noise(rng), false);
        }
    PointCloud with_line = f.cloud, without_line = f.cloud;
    const Report r = remove_distance_outliers(with_line, DistanceOptions{});
    DistanceOptions no_line;
    no_line.line_sigmas = 0.0;
    remove_distance_outliers(without_line, no_line);
    const Score s = score(f, with_line), s0 = score(f, without_line);
    EXPECT_GE(s.recall, 0.95) << r.dump();
    EXPECT_LE(s.inlier_loss, 0.005) << r.dump();
    EXPECT_LT(s0.recall, 0.5);  // the window test alone keeps most of them
}

// A sphere (radius 0.15 m, centre 1.5 m) in front of a wall at 1.75 m, rendered the way
// rgbd-synth does: axial noise sigma_z(z, theta) with the grazing term, dropouts ramping from
// 70 to 85 degrees of incidence plus 0.5% random ones, and in the 2-pixel band around every
// depth jump > 30 mm, half the pixels replaced by flying pixels fg + U (bg - fg) (fg, bg = the
// nearest and farthest clean depth in the 3 x 3 neighbourhood). The true distance of every
// point to the scene is known in closed form: flying pixels farther than 8 mm from both
// surfaces must go, surface pixels must stay (flying pixels nearer than 8 mm count for
// neither, as in measure_denoise.py's geometric metric).
struct SphereScene {
    Frame frame;
    std::set<std::uint32_t> far_flying;  ///< flying pixels > 8 mm from the true surfaces
    std::set<std::uint32_t> surface;     ///< sphere and wall pixels
};

SphereScene sphere_scene(std::uint64_t seed) {
    SphereScene out;
    out.frame = empty_frame();
    const auto k = intrinsics();
    const Eigen::Vector3d centre(0.0, 0.0, 1.5);
    const double radius = 0.15, wall = 1.75;
    std::vector<double> depth(std::size_t(kW) * kH), theta(std::size_t(kW) * kH);
    for (int row = 0; row < kH; ++row)
        for (int col = 0; col < kW; ++col) {
            const Eigen::Vector3d d = k.unproject(col, row, 1.0);  // d.z() = 1
            const double b = d.dot(centre), c = centre.squaredNorm() - radius * radius;
            const double disc = b * b - d.squaredNorm() * c;
            const std::size_t at = std::size_t(row) * kW + col;
            if (disc >= 0.0) {
                const double t = (b - std::sqrt(disc)) / d.squaredNorm();
                const Eigen::Vector3d n = (t * d - centre) / radius;
                depth[at] = t;
                theta[at] = std::acos(std::min(1.0, std::abs(n.dot(d.normalized()))));
            } else {
                depth[at] = wall;
                theta[at] = std::acos(1.0 / d.norm());
            }
        }
    const auto true_distance = [&](const Eigen::Vector3d& p) {
        return std::min(std::abs((p - centre).norm() - radius), std::abs(p.z() - wall));
    };
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    std::normal_distribution<double> normal(0.0, 1.0);
    const double deg = std::numbers::pi / 180.0;
    for (int row = 0; row < kH; ++row)
        for (int col = 0; col < kW; ++col) {
            const std::size_t at = std::size_t(row) * kW + col;
            double fg = depth[at], bg = depth[at];
            for (int dr = -1; dr <= 1; ++dr)
                for (int dc = -1; dc <= 1; ++dc) {
                    const int rr = std::clamp(row + dr, 0, kH - 1);
                    const int cc = std::clamp(col + dc, 0, kW - 1);
                    fg = std::min(fg, depth[std::size_t(rr) * kW + cc]);
                    bg = std::max(bg, depth[std::size_t(rr) * kW + cc]);
                }
            const auto px = std::uint32_t(at);
            if (bg - fg > 0.03 && uniform(rng) < 0.5) {
                const double z = fg + uniform(rng) * (bg - fg);
                const bool far = true_distance(k.unproject(col, row, z)) > 0.008;
                add(out.frame, col, row, z, true);
                if (far) out.far_flying.insert(px);
                continue;
            }
            const double ramp = std::clamp((theta[at] / deg - 70.0) / 15.0, 0.0, 1.0);
            if (uniform(rng) < ramp || uniform(rng) < 0.005) continue;  // dropout
            const double sigma = sigma_z_m(NoiseModel::kKinectV2, depth[at], theta[at]);
            add(out.frame, col, row, depth[at] + sigma * normal(rng), false);
            out.surface.insert(px);
        }
    return out;
}

/// Recall over `noise` and loss over `surface` of the pixels missing from `after`.
std::pair<double, double> recall_and_loss(const std::set<std::uint32_t>& noise,
                                          const std::set<std::uint32_t>& surface,
                                          const PointCloud& after) {
    std::set<std::uint32_t> kept;
    const auto pixel = *after.pixel_map();
    for (auto idx : after.points) kept.insert(pixel[idx]);
    std::size_t removed_noise = 0, removed_surface = 0;
    for (auto px : noise) removed_noise += !kept.count(px);
    for (auto px : surface) removed_surface += !kept.count(px);
    return {double(removed_noise) / double(noise.size()),
            double(removed_surface) / double(surface.size())};
}

TEST(DistanceOutliers, SphereBeforeAWallFarFlyingPixelsGoSurfaceStays) {
    for (std::uint64_t seed : {1, 2, 3}) {
        const SphereScene scene = sphere_scene(seed);
        ASSERT_GT(scene.far_flying.size(), 100u);
        ASSERT_GT(scene.surface.size(), 15000u);
        PointCloud cloud = scene.frame.cloud;
        const Report r = remove_distance_outliers(cloud, DistanceOptions{});
        const auto [recall, loss] = recall_and_loss(scene.far_flying, scene.surface, cloud);
        EXPECT_GE(recall, 0.9) << "seed " << seed << " " << r.dump();
        EXPECT_LE(loss, 0.002) << "seed " << seed << " " << r.dump();
    }
}

// A plane at 78 degrees of incidence, rgbd-synth style: axial noise with the grazing term
// (~7 mm at 1.5 m) and dropouts (35%, as the 70-85 degree ramp gives there). Its pixels often
// fail the support and line tests; their 5 nearest 3D points stay within 3 footprints, so the
// kNN keep test keeps them.
TEST(DistanceOutliers, KnnKeepTestKeepsNoisyGrazingSurface) {
    const Frame f = tilted_plane(78.0, 1.0, 2.0, 0.35, 9);
    ASSERT_GT(f.surface, 3000u);
    PointCloud with_keep = f.cloud, without_keep = f.cloud;
    const Report r = remove_distance_outliers(with_keep, DistanceOptions{});
    DistanceOptions no_keep;
    no_keep.keep_knn = 0.0;
    const Report r0 = remove_distance_outliers(without_keep, no_keep);
    const double loss = 1.0 - double(with_keep.size()) / double(f.surface);
    const double loss0 = 1.0 - double(without_keep.size()) / double(f.surface);
    EXPECT_LE(loss, 0.02) << r.dump();
    EXPECT_GT(loss0, 2.0 * loss + 0.005) << r0.dump();
}

TEST(DistanceOutliers, InlierLossDoesNotDependOnDepth) {
    Frame near = object_scene(1.0, 7);
    Frame far = object_scene(3.0, 7);
    PointCloud a = near.cloud, b = far.cloud;
    remove_distance_outliers(a, DistanceOptions{});
    remove_distance_outliers(b, DistanceOptions{});
    const Score sa = score(near, a), sb = score(far, b);
    EXPECT_LT(std::abs(sa.inlier_loss - sb.inlier_loss), 0.01);
    EXPECT_GE(sa.recall, 0.95);
    EXPECT_GE(sb.recall, 0.95);
}

TEST(DistanceOutliers, MarkEqualsDelete) {
    Frame f = object_scene(1.5);
    PointCloud deleted = f.cloud, marked = f.cloud;
    DistanceOptions o;
    remove_distance_outliers(deleted, o);
    o.mark = true;
    const Report r = remove_distance_outliers(marked, o);
    EXPECT_EQ(marked.size(), f.cloud.size());
    std::set<std::uint32_t> a, b;
    for (auto idx : deleted.points) a.insert((*deleted.pixel_map())[idx]);
    const auto noise = *marked.flag(prop::kNoise);
    for (auto idx : marked.points)
        if (!noise[idx]) b.insert((*marked.pixel_map())[idx]);
    EXPECT_EQ(a, b);
    EXPECT_EQ(r["marked"].get<std::size_t>(), f.cloud.size() - deleted.size());
}

TEST(DistanceOutliers, WorldFrameAndEstimatedFocalGiveTheSameResult) {
    Frame f = object_scene(1.5);
    PointCloud sensor = f.cloud;
    remove_distance_outliers(sensor, DistanceOptions{});
    PointCloud world = f.cloud;
    Pose pose = Pose::Identity();
    pose.rotate(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()));
    pose.translation() = Eigen::Vector3d(0.3, -1.0, 2.0);
    transform(world, pose);
    world.view.frame = ViewFrame::kWorld;
    world.view.world_from_sensor = pose;
    world.view.intrinsics.reset();
    const Report r = remove_distance_outliers(world, DistanceOptions{});
    EXPECT_NEAR(r["focal_px"].get<double>(), kF, 0.5);
    EXPECT_EQ(world.size(), sensor.size());
}

TEST(DistanceOutliers, Errors) {
    Frame f = object_scene(1.5);
    PointCloud nan = f.cloud;
    nan.points.insert(Point_3(0, std::numeric_limits<double>::quiet_NaN(), 1));
    EXPECT_THROW(remove_distance_outliers(nan, DistanceOptions{}), InputError);

    PointCloud no_grid = f.cloud;
    no_grid.view.grid_width = no_grid.view.grid_height = 0;
    expect_input_error([&] { remove_distance_outliers(no_grid, DistanceOptions{}); },
                       {"--density", "view 3"});
    PointCloud world = f.cloud;
    world.view.frame = ViewFrame::kWorld;
    EXPECT_THROW(remove_distance_outliers(world, DistanceOptions{}), InputError);

    EXPECT_TRUE(rejects<DistanceOptions>([](auto& o) { o.c_min = 25; }));
    EXPECT_TRUE(rejects<DistanceOptions>([](auto& o) { o.theta_max_deg = 90; }));
    EXPECT_TRUE(rejects<DistanceOptions>([](auto& o) { o.alpha = -1; }));
    EXPECT_TRUE(rejects<DistanceOptions>([](auto& o) { o.c_min_wide = 49; }));
    EXPECT_TRUE(rejects<DistanceOptions>(
        [](auto& o) { o.keep_knn = std::numeric_limits<double>::quiet_NaN(); }));
    EXPECT_TRUE(rejects<DistanceOptions>([](auto& o) { o.keep_k = 0; }));
    EXPECT_TRUE(rejects<DistanceOptions>([](auto& o) { o.keep_k = 49; }));
}

TEST(DistanceOutliers, EmptyViewsPass) {
    PointCloud empty;
    EXPECT_EQ(remove_distance_outliers(empty, DistanceOptions{})["removed"].get<int>(), 0);
    Frame f = empty_frame();
    EXPECT_EQ(remove_distance_outliers(f.cloud, DistanceOptions{})["removed"].get<int>(), 0);
}

TEST(DistanceOutliers, OneAndTwoThreadsAgree) {
    Frame f = object_scene(2.0, 11);
    PointCloud one = f.cloud, two = f.cloud;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        remove_distance_outliers(one, DistanceOptions{});
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
        remove_distance_outliers(two, DistanceOptions{});
    }
    ASSERT_EQ(one.size(), two.size());
    auto a = one.points.begin();
    for (auto b : two.points) EXPECT_EQ(one.points.point(*a++), two.points.point(b));
}

TEST(SensorNoise, KinectV2AtOnePointFiveMetres) {
    EXPECT_NEAR(sigma_z_m(NoiseModel::kKinectV2, 1.5), 0.0014, 0.0001);
    // dz_max(1.5 m) ~ 4.1 mm * 3.73 + 3 * 1.4 mm ~ 19.5 mm (docs/algorithms.md §4).
    EXPECT_NEAR(max_depth_step_m(NoiseModel::kKinectV2, 1.5, kF, 75 * std::numbers::pi / 180),
                0.0195, 0.001);
    EXPECT_EQ(parse_noise_model("sr300"), NoiseModel::kSr300);
    EXPECT_THROW(parse_noise_model("kinect"), InputError);
}

}  // namespace
}  // namespace rgbd::denoise
