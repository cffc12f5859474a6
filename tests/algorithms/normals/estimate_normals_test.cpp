#include "algorithms/normals/estimate_normals.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <random>

#include "toolkit/error.hpp"

namespace {

using rgbd::PointCloud;
using rgbd::normals::NormalOptions;
using rgbd::normals::NormalOrientation;

constexpr double kRadius = 0.1;

/// Fibonacci samples of a sphere (centre c, radius 0.1 m), optionally only the part with
/// (p - c).dot(towards) > 0.
PointCloud sphere(int n, const Eigen::Vector3d& c, const Eigen::Vector3d* towards = nullptr) {
    PointCloud cloud;
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double y = 1.0 - 2.0 * (i + 0.5) / n;
        const double r = std::sqrt(1.0 - y * y);
        const Eigen::Vector3d u(r * std::cos(golden * i), y, r * std::sin(golden * i));
        if (towards && u.dot(*towards) <= 0.2) continue;
        cloud.points.insert(rgbd::to_point(c + kRadius * u));
    }
    return cloud;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

TEST(EstimateNormals, SphereOutward) {
    const Eigen::Vector3d c(0.3, -0.2, 1.0);
    PointCloud cloud = sphere(20000, c);
    cloud.view.frame = rgbd::ViewFrame::kWorld;
    NormalOptions options;
    options.orientation = NormalOrientation::kOutward;
    const rgbd::Report report = rgbd::normals::estimate_normals(cloud, options);
    EXPECT_EQ(report["orientation"], "outward");
    ASSERT_TRUE(cloud.points.has_normal_map());
    double worst = 0;
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = rgbd::to_eigen(cloud.points.point(idx));
        worst = std::max(worst, angle_deg(rgbd::to_eigen(cloud.points.normal(idx)), p - c));
    }
    EXPECT_LT(worst, 2.0);
}

TEST(EstimateNormals, SensorFrameViewPointsTowardsTheOrigin) {
    // Sphere 0.8 m in front of the sensor; only the part facing the sensor is seen.
    const Eigen::Vector3d c(0.05, 0.0, 0.8);
    const Eigen::Vector3d towards = -c.normalized();
    PointCloud cloud = sphere(40000, c, &towards);
    cloud.view.frame = rgbd::ViewFrame::kSensor;
    const rgbd::Report report = rgbd::normals::estimate_normals(cloud, NormalOptions{});
    EXPECT_EQ(report["orientation"], "sensor");
    double worst = 0;
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = rgbd::to_eigen(cloud.points.point(idx));
        const Eigen::Vector3d n = rgbd::to_eigen(cloud.points.normal(idx));
        EXPECT_GT(n.dot(-p), 0.0);
        // Rim points have one-sided neighbourhoods; the truth check skips a 1 cm band.
        if ((p - c).normalized().dot(towards) > 0.35) worst = std::max(worst, angle_deg(n, p - c));
    }
    EXPECT_LT(worst, 2.0);
}

TEST(EstimateNormals, WorldFrameViewUsesItsSensorPose) {
    const Eigen::Vector3d c(0, 0, 0);
    const Eigen::Vector3d camera(1.0, 0.2, 0.0);
    const Eigen::Vector3d towards = camera.normalized();
    PointCloud cloud = sphere(20000, c, &towards);
    cloud.view.frame = rgbd::ViewFrame::kWorld;
    rgbd::Pose pose = rgbd::Pose::Identity();
    pose.translation() = camera;
    cloud.view.world_from_sensor = pose;
    rgbd::normals::estimate_normals(cloud, NormalOptions{});
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = rgbd::to_eigen(cloud.points.point(idx));
        EXPECT_GT(rgbd::to_eigen(cloud.points.normal(idx)).dot(camera - p), 0.0);
    }
}

TEST(EstimateNormals, MergedCloudMstIsConsistentlyOutward) {
    PointCloud cloud = sphere(8000, Eigen::Vector3d(0, 0, 0.5));
    cloud.view.frame = rgbd::ViewFrame::kWorld;
    cloud.view.sensor = "merged";
    const rgbd::Report report = rgbd::normals::estimate_normals(cloud, NormalOptions{});
    EXPECT_EQ(report["orientation"], "mst");
    std::size_t outward = 0;
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = rgbd::to_eigen(cloud.points.point(idx));
        if (rgbd::to_eigen(cloud.points.normal(idx)).dot(p - Eigen::Vector3d(0, 0, 0.5)) > 0)
            ++outward;
    }
    EXPECT_EQ(outward, cloud.size());
}

TEST(EstimateNormals, NoisyPlane) {
    PointCloud cloud;
    std::mt19937 rng(11);
    std::normal_distribution<double> noise(0.0, 0.0005);
    const Eigen::Vector3d normal = Eigen::Vector3d(0.2, -0.3, 1.0).normalized();
    const Eigen::Vector3d e1 = normal.unitOrthogonal(), e2 = normal.cross(e1);
    for (int y = 0; y < 100; ++y)
        for (int x = 0; x < 100; ++x)
            cloud.points.insert(rgbd::to_point(Eigen::Vector3d(0, 0, 1.2) + 0.005 * x * e1 +
                                               0.005 * y * e2 + noise(rng) * normal));
    cloud.view.frame = rgbd::ViewFrame::kSensor;
    rgbd::normals::estimate_normals(cloud, NormalOptions{});
    double sum = 0;
    for (auto idx : cloud.points) {
        const Eigen::Vector3d n = rgbd::to_eigen(cloud.points.normal(idx));
        sum += angle_deg(n, normal.z() < 0 ? normal : -normal);  // towards the origin
    }
    EXPECT_LT(sum / cloud.size(), 3.0);
}

TEST(EstimateNormals, SameResultForAnyThreadCount) {
    PointCloud a = sphere(20000, Eigen::Vector3d(0, 0, 1));
    a.view.frame = rgbd::ViewFrame::kSensor;
    PointCloud b = a;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        rgbd::normals::estimate_normals(a, NormalOptions{});
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
        rgbd::normals::estimate_normals(b, NormalOptions{});
    }
    auto ib = b.points.begin();
    for (auto idx : a.points) EXPECT_EQ(a.points.normal(idx), b.points.normal(*ib++));
}

/// An organised view as rgbd-cloud and super-resolution make it: a 160 x 120 depth grid (focal
/// 150 px) seeing a sphere (radius 0.1 m at 0.7 m) in front of a wall at 1.0 m, with
/// `per_pixel` points per pixel on rays spread within the pixel (super-resolution's children).
/// `truth` receives each point's true normal, towards the sensor.
PointCloud organised_scene(int per_pixel, std::vector<Eigen::Vector3d>& truth) {
    PointCloud cloud;
    cloud.view.frame = rgbd::ViewFrame::kSensor;
    cloud.view.grid_width = 160;
    cloud.view.grid_height = 120;
    auto pixel = cloud.add_pixel_map();
    const Eigen::Vector3d c(0.0, 0.0, 0.7);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> sub(-0.5, 0.5);
    for (int row = 0; row < 120; ++row)
        for (int col = 0; col < 160; ++col)
            for (int s = 0; s < per_pixel; ++s) {
                const double u = col + (s ? sub(rng) : 0.0), v = row + (s ? sub(rng) : 0.0);
                const Eigen::Vector3d ray =
                    Eigen::Vector3d((u - 79.5) / 150.0, (v - 59.5) / 150.0, 1.0).normalized();
                // Nearest hit: the sphere, else the wall z = 1.
                const double b = ray.dot(c), disc = b * b - (c.squaredNorm() - kRadius * kRadius);
                Eigen::Vector3d p, n;
                if (disc > 0) {
                    p = (b - std::sqrt(disc)) * ray;
                    n = (p - c).normalized();
                } else {
                    p = ray / ray.z();
                    n = -Eigen::Vector3d::UnitZ();
                }
                const auto idx = *cloud.points.insert(rgbd::to_point(p));
                pixel[idx] = static_cast<std::uint32_t>(row * 160 + col);
                truth.push_back(n);
            }
    return cloud;
}

TEST(EstimateNormals, OrganisedViewsTakeNeighboursFromThePixelWindow) {
    for (const int per_pixel : {1, 5}) {
        std::vector<Eigen::Vector3d> truth;
        PointCloud grid = organised_scene(per_pixel, truth);
        PointCloud tree = grid;
        NormalOptions options;
        const rgbd::Report report = rgbd::normals::estimate_normals(grid, options);
        EXPECT_EQ(report["neighbours"]["method"], "pixel_grid");
        options.pixel_grid = false;
        const rgbd::Report tree_report = rgbd::normals::estimate_normals(tree, options);
        EXPECT_EQ(tree_report["neighbours"]["method"], "knn");
        std::size_t same = 0, off_truth = 0, i = 0;
        auto it = tree.points.begin();
        for (auto idx : grid.points) {
            const Eigen::Vector3d n = rgbd::to_eigen(grid.points.normal(idx));
            if (angle_deg(n, rgbd::to_eigen(tree.points.normal(*it++))) < 2.0) ++same;
            if (angle_deg(n, truth[i++]) > 5.0) ++off_truth;  // the sphere's silhouette
        }
        // One PCA per pixel from the k points of its window nearest to the pixel's first point:
        // within 2 deg of the kd-tree's per-point kNN almost everywhere (not along the sphere's
        // silhouette), and as close to the truth.
        EXPECT_GT(same, 0.97 * grid.size()) << per_pixel << " points per pixel";
        EXPECT_LT(off_truth, 0.03 * grid.size()) << per_pixel << " points per pixel";
    }
}

/// A point per pixel on a wavy surface whose depth (a function of the row) is quantised to 1 mm:
/// a pixel's left and right neighbours lie at exactly the same squared distance.
/// An 80 x 60 sensor-frame view of a curved surface with depths quantised to 1 mm. `dyadic`:
/// every coordinate a multiple of 1/64 instead, so squared distances are exact and many equal,
/// and the window's distance bounds fall exactly on them.
PointCloud quantised_view(bool dyadic = false) {
    PointCloud cloud;
    cloud.view.frame = rgbd::ViewFrame::kSensor;
    cloud.view.grid_width = 80;
    cloud.view.grid_height = 60;
    auto pixel = cloud.add_pixel_map();
    for (int row = 0; row < 60; ++row)
        for (int col = 0; col < 80; ++col) {
            const double x = (col - 39.5) / 75.0, y = (row - 29.5) / 75.0;
            const double z =
                std::round(1000.0 * (1.0 + 0.02 * std::sin(8.0 * y) + 0.1 * y * y)) / 1000.0;
            const Eigen::Vector3d p =
                dyadic
                    ? Eigen::Vector3d(
                          (col - 40) / 64.0, (row - 30) / 64.0,
                          std::round(64.0 * (1.0 + 0.25 * std::sin(5.0 * y) + 0.2 * x * x)) / 64.0)
                    : Eigen::Vector3d(x * z, y * z, z);
            const auto idx = *cloud.points.insert(rgbd::to_point(p));
            pixel[idx] = static_cast<std::uint32_t>(row * 80 + col);
        }
    return cloud;
}

/// Every pixel's normal is the PCA normal of the k points of its window nearest to it, ties by
/// index (the reference sorts the whole window).
void expect_window_neighbours(bool dyadic) {
    SCOPED_TRACE(dyadic ? "dyadic coordinates" : "1 mm depths");
    PointCloud cloud = quantised_view(dyadic);
    std::vector<Eigen::Vector3d> xyz;
    for (auto idx : cloud.points) xyz.push_back(rgbd::to_eigen(cloud.points.point(idx)));
    const NormalOptions options;
    const rgbd::Report report = rgbd::normals::estimate_normals(cloud, options);
    const int h = report["neighbours"]["half_window_px"];
    const std::size_t k = static_cast<std::size_t>(options.k);
    // The reference: every point of the window, sorted by (squared distance, index), the first
    // k; their PCA normal. Point i is pixel i here.
    std::size_t ties_at_k = 0, i = 0;
    for (auto idx : cloud.points) {
        const int row = static_cast<int>(i / 80), col = static_cast<int>(i % 80);
        std::vector<std::pair<double, std::size_t>> window;
        for (int r = std::max(0, row - h); r <= std::min(59, row + h); ++r)
            for (int c = std::max(0, col - h); c <= std::min(79, col + h); ++c)
                window.emplace_back((xyz[r * 80 + c] - xyz[i]).squaredNorm(), r * 80 + c);
        std::sort(window.begin(), window.end());
        if (window.size() <= k) {  // a corner: all of its window
            ++i;
            continue;
        }
        ties_at_k += window[k - 1].first == window[k].first;
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (std::size_t j = 0; j < k; ++j) mean += xyz[window[j].second];
        mean /= static_cast<double>(k);
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        for (std::size_t j = 0; j < k; ++j) {
            const Eigen::Vector3d d = xyz[window[j].second] - mean;
            cov += d * d.transpose();
        }
        const Eigen::Vector3d expected =
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
        const Eigen::Vector3d n = rgbd::to_eigen(cloud.points.normal(idx));
        ASSERT_GT(std::abs(n.normalized().dot(expected.normalized())), 1.0 - 1e-12)
            << "pixel " << i;
        ++i;
    }
    // The k-th and (k+1)-th nearest at the same distance: only the index decides between them.
    EXPECT_GT(ties_at_k, 100u);
}

TEST(EstimateNormals, PixelWindowTakesTheKNearestWithTiesByIndex) {
    expect_window_neighbours(false);
    expect_window_neighbours(true);
}

TEST(EstimateNormals, BadInput) {
    PointCloud cloud;
    cloud.view.id = 9;
    cloud.points.insert(rgbd::Point_3(0, 0, 0));
    cloud.points.insert(rgbd::Point_3(1, 0, 0));
    EXPECT_THROW(rgbd::normals::estimate_normals(cloud, NormalOptions{}), rgbd::InputError);
    NormalOptions bad;
    bad.k = 2;
    EXPECT_THROW(bad.check(), rgbd::InputError);
    PointCloud world = sphere(100, Eigen::Vector3d(0, 0, 0));
    world.view.frame = rgbd::ViewFrame::kWorld;
    NormalOptions sensor;
    sensor.orientation = NormalOrientation::kSensor;
    EXPECT_THROW(rgbd::normals::estimate_normals(world, sensor), rgbd::InputError);
}

}  // namespace
