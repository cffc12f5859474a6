// Tests of statistical and radius outlier removal: synthetic plane with far outliers, hand-
// computed examples of both conventions, mark vs delete, property alignment, edge cases,
// thread-count determinism, and (when python3-open3d is installed) identity with Open3D.
#include "algorithms/denoise/statistical_outliers.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include "tests/support/input_error.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {
namespace {

using rgbd::test::expect_input_error;

/// Cloud from coordinates; the `pixel` property holds the original index.
PointCloud make_cloud(const std::vector<Eigen::Vector3d>& xyz) {
    PointCloud cloud;
    cloud.view.id = 4;
    cloud.view.sensor = "k2-1";
    auto pixel = cloud.add_pixel_map();
    auto colors = cloud.add_colors();
    for (std::size_t i = 0; i < xyz.size(); ++i) {
        auto idx = *cloud.points.insert(to_point(xyz[i]));
        pixel[idx] = static_cast<std::uint32_t>(i);
        colors.set(idx, Rgb{std::uint8_t(i % 251), std::uint8_t(i / 251 % 251), 7});
    }
    return cloud;
}

/// Noisy 100 x 100 plane (5 mm spacing) followed by `outliers` far points.
std::vector<Eigen::Vector3d> plane_with_outliers(std::size_t outliers, std::uint64_t seed = 3) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0.0, 0.0003);
    std::uniform_real_distribution<double> box(-0.2, 0.7);
    std::uniform_real_distribution<double> height(0.1, 0.6);
    std::vector<Eigen::Vector3d> xyz;
    for (int i = 0; i < 100; ++i)
        for (int j = 0; j < 100; ++j) xyz.emplace_back(0.005 * i, 0.005 * j, noise(rng));
    for (std::size_t k = 0; k < outliers; ++k) xyz.emplace_back(box(rng), box(rng), height(rng));
    return xyz;
}

std::set<std::uint32_t> kept(const PointCloud& cloud) {
    std::set<std::uint32_t> out;
    const auto pixel = *cloud.pixel_map();
    for (auto idx : cloud.points) out.insert(pixel[idx]);
    return out;
}

std::set<std::uint32_t> unmarked(const PointCloud& cloud) {
    std::set<std::uint32_t> out;
    const auto pixel = *cloud.pixel_map();
    const auto noise = cloud.flag(prop::kNoise);
    for (auto idx : cloud.points)
        if (!noise || (*noise)[idx] == 0) out.insert(pixel[idx]);
    return out;
}

TEST(StatisticalOutliers, PlaneWithFarOutliers) {
    const auto xyz = plane_with_outliers(50);
    for (auto convention : {OutlierConvention::kOpen3d, OutlierConvention::kPcl}) {
        PointCloud cloud = make_cloud(xyz);
        StatisticalOptions options;
        options.convention = convention;
        const Report report = remove_statistical_outliers(cloud, options);
        const auto survivors = kept(cloud);
        std::size_t inliers_removed = 0;
        for (std::uint32_t i = 0; i < 10000; ++i) inliers_removed += !survivors.count(i);
        for (std::uint32_t i = 10000; i < xyz.size(); ++i) EXPECT_FALSE(survivors.count(i)) << i;
        EXPECT_LT(inliers_removed, 100u);
        EXPECT_EQ(report["removed"].get<std::size_t>(), xyz.size() - cloud.size());
        EXPECT_EQ(report["k"].get<int>(), 20);
        EXPECT_GT(report["threshold_m"].get<double>(), 0.0);
    }
}

TEST(StatisticalOutliers, MarkFlagsExactlyWhatDeleteRemoves) {
    const auto xyz = plane_with_outliers(80, 11);
    for (auto convention : {OutlierConvention::kOpen3d, OutlierConvention::kPcl}) {
        StatisticalOptions options;
        options.convention = convention;
        options.std_ratio = 1.0;  // removes some inliers too: a stronger comparison
        PointCloud deleted = make_cloud(xyz);
        remove_statistical_outliers(deleted, options);
        PointCloud marked = make_cloud(xyz);
        options.mark = true;
        const Report report = remove_statistical_outliers(marked, options);
        EXPECT_EQ(marked.size(), xyz.size());
        EXPECT_EQ(unmarked(marked), kept(deleted));
        EXPECT_EQ(report["marked"].get<std::size_t>(), xyz.size() - deleted.size());
    }
}

std::vector<Eigen::Vector3d> line_points() {
    return {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {10, 0, 0}};
}

TEST(StatisticalOutliers, Open3dRuleOnHandExample) {
    // k = 2 with self: mean distances 0.5 0.5 0.5 0.5 3.5; mean 1.1, std (Bessel) sqrt(1.8).
    StatisticalOptions options;
    options.k = 2;
    options.std_ratio = 1.0;  // threshold 2.4416: the far point goes
    PointCloud cloud = make_cloud(line_points());
    Report report = remove_statistical_outliers(cloud, options);
    EXPECT_EQ(kept(cloud), (std::set<std::uint32_t>{0, 1, 2, 3}));
    EXPECT_NEAR(report["mean_distance_m"].get<double>(), 1.1, 1e-12);
    EXPECT_NEAR(report["std_distance_m"].get<double>(), std::sqrt(1.8), 1e-12);
    options.std_ratio = 1.8;  // threshold 3.515 > 3.5: all stay
    cloud = make_cloud(line_points());
    remove_statistical_outliers(cloud, options);
    EXPECT_EQ(cloud.size(), 5u);
    // Strictly below: four square corners, all means 0.5 = threshold -> Open3D drops all.
    cloud = make_cloud({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}});
    options.std_ratio = 1.0;
    remove_statistical_outliers(cloud, options);
    EXPECT_EQ(cloud.size(), 0u);
    // Duplicates only among the k (mean distance 0) are removed, as in Open3D.
    cloud = make_cloud({{0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}});
    options.std_ratio = 2.0;
    remove_statistical_outliers(cloud, options);
    EXPECT_EQ(kept(cloud), (std::set<std::uint32_t>{2, 3, 4}));
}

TEST(StatisticalOutliers, PclRuleOnHandExample) {
    // k = 2 without self: 1.5 1 1 1.5 7.5; mean 2.5, std sqrt(7.875) = 2.806.
    StatisticalOptions options;
    options.convention = OutlierConvention::kPcl;
    options.k = 2;
    options.std_ratio = 1.8;  // threshold 7.551: all stay
    PointCloud cloud = make_cloud(line_points());
    Report report = remove_statistical_outliers(cloud, options);
    EXPECT_EQ(cloud.size(), 5u);
    EXPECT_NEAR(report["mean_distance_m"].get<double>(), 2.5, 1e-6);
    EXPECT_NEAR(report["std_distance_m"].get<double>(), std::sqrt(7.875), 1e-6);
    options.std_ratio = 1.78;  // threshold 6.495: the far point goes
    cloud = make_cloud(line_points());
    remove_statistical_outliers(cloud, options);
    EXPECT_EQ(kept(cloud), (std::set<std::uint32_t>{0, 1, 2, 3}));
    // Less or equal: square corners, k = 1, all means 1 = threshold -> PCL keeps all.
    options.k = 1;
    options.std_ratio = 1.0;
    cloud = make_cloud({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}});
    remove_statistical_outliers(cloud, options);
    EXPECT_EQ(cloud.size(), 4u);
}

TEST(StatisticalOutliers, PropertiesStayAligned) {
    const auto xyz = plane_with_outliers(200, 5);
    PointCloud cloud = make_cloud(xyz);
    StatisticalOptions options;
    options.std_ratio = 0.5;
    remove_statistical_outliers(cloud, options);
    ASSERT_LT(cloud.size(), xyz.size());
    const auto pixel = *cloud.pixel_map();
    const auto colors = cloud.colors();
    std::uint32_t previous = 0;
    bool first = true;
    for (auto idx : cloud.points) {
        const std::uint32_t i = pixel[idx];
        EXPECT_EQ(to_eigen(cloud.points.point(idx)), xyz[i]);
        EXPECT_EQ(colors.get(idx), (Rgb{std::uint8_t(i % 251), std::uint8_t(i / 251 % 251), 7}));
        if (!first) {
            EXPECT_GT(i, previous) << "order preserved";
        }
        previous = i;
        first = false;
    }
    EXPECT_EQ(cloud.points.number_of_removed_points(), 0u);
}

TEST(StatisticalOutliers, EdgeCases) {
    PointCloud empty;
    Report report = remove_statistical_outliers(empty, StatisticalOptions{});
    EXPECT_EQ(report["removed"].get<int>(), 0);
    report = remove_radius_outliers(empty, RadiusOptions{});
    EXPECT_EQ(report["removed"].get<int>(), 0);

    PointCloud small = make_cloud(line_points());
    report = remove_statistical_outliers(small, StatisticalOptions{});
    EXPECT_TRUE(report["k_clamped"].get<bool>());
    EXPECT_EQ(report["k"].get<int>(), 5);
    small = make_cloud(line_points());
    StatisticalOptions pcl;
    pcl.convention = OutlierConvention::kPcl;
    report = remove_statistical_outliers(small, pcl);
    EXPECT_EQ(report["k"].get<int>(), 4);

    PointCloud bad = make_cloud({{0, 0, 0}, {std::nan(""), 0, 0}});
    expect_input_error([&] { remove_statistical_outliers(bad, StatisticalOptions{}); }, {"view 4"});
    EXPECT_THROW(remove_radius_outliers(bad, RadiusOptions{}), InputError);
    StatisticalOptions absurd;
    absurd.k = 0;
    EXPECT_THROW(remove_statistical_outliers(small, absurd), InputError);

    // Cancel leaves the cloud unchanged.
    PointCloud cloud = make_cloud(plane_with_outliers(10));
    report =
        remove_statistical_outliers(cloud, StatisticalOptions{}, [](double f) { return f < 0.5; });
    EXPECT_TRUE(report["cancelled"].get<bool>());
    EXPECT_EQ(cloud.size(), 10010u);
}

TEST(RadiusOutliers, BoundaryRuleOfEachConvention) {
    // Points 1 m apart, radius 1, min_points 1: Open3D counts d < r (strict), PCL d <= r.
    RadiusOptions options;
    options.min_points = 1;
    options.radius_m = 1.0;
    PointCloud cloud = make_cloud({{0, 0, 0}, {1, 0, 0}, {5, 0, 0}});
    remove_radius_outliers(cloud, options);
    EXPECT_EQ(cloud.size(), 0u);
    options.convention = OutlierConvention::kPcl;
    cloud = make_cloud({{0, 0, 0}, {1, 0, 0}, {5, 0, 0}});
    remove_radius_outliers(cloud, options);
    EXPECT_EQ(kept(cloud), (std::set<std::uint32_t>{0, 1}));
    // Count includes the point itself: min_points 0 keeps everything.
    options.min_points = 0;
    cloud = make_cloud({{0, 0, 0}, {1, 0, 0}, {5, 0, 0}});
    remove_radius_outliers(cloud, options);
    EXPECT_EQ(cloud.size(), 3u);
}

TEST(RadiusOutliers, RadiusFromSpacingRemovesFarOutliers) {
    const auto xyz = plane_with_outliers(50);
    PointCloud cloud = make_cloud(xyz);
    RadiusOptions options;
    options.min_points = 8;
    options.radius_spacing_factor = 3.0;
    const Report report = remove_radius_outliers(cloud, options);
    EXPECT_NEAR(report["spacing_m"].get<double>(), 0.005, 0.0005);
    EXPECT_NEAR(report["radius_m"].get<double>(), 0.015, 0.0015);
    const auto survivors = kept(cloud);
    for (std::uint32_t i = 10000; i < xyz.size(); ++i) EXPECT_FALSE(survivors.count(i));
    EXPECT_EQ(survivors.size(), 10000u);  // 3 s_hat holds >= 28 neighbours even at corners
}

TEST(StatisticalOutliers, SameResultForOneAndManyThreads) {
    const auto xyz = plane_with_outliers(300, 9);
    StatisticalOptions options;
    options.std_ratio = 1.0;
    PointCloud many = make_cloud(xyz);
    const Report r_many = remove_statistical_outliers(many, options);
    PointCloud one = make_cloud(xyz);
    Report r_one;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        r_one = remove_statistical_outliers(one, options);
    }
    EXPECT_EQ(kept(one), kept(many));
    EXPECT_EQ(r_one["threshold_m"].get<double>(), r_many["threshold_m"].get<double>());
}

bool open3d_available() {
    return std::system("/usr/bin/python3 -c \"import open3d\" > /dev/null 2>&1") == 0;
}

/// Runs Open3D's filter on the cloud written as .xyz and returns the kept indices.
std::set<std::uint32_t> open3d_kept(const std::vector<Eigen::Vector3d>& xyz,
                                    const std::string& call) {
    const auto dir =
        std::filesystem::temp_directory_path() /
        ("rgbd_sor_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
         std::to_string(std::rand()));
    std::filesystem::create_directories(dir);
    {
        std::ofstream out(dir / "cloud.xyz");
        char line[128];
        for (const auto& p : xyz) {
            std::snprintf(line, sizeof line, "%.17g %.17g %.17g\n", p.x(), p.y(), p.z());
            out << line;
        }
        std::ofstream py(dir / "run.py");
        py << "import open3d as o3d\n"
           << "p = o3d.io.read_point_cloud('" << (dir / "cloud.xyz").string()
           << "', format='xyz')\n"
           << "_, ind = p." << call << "\n"
           << "print(' '.join(str(i) for i in ind))\n";
    }
    const std::string cmd = "/usr/bin/python3 " + (dir / "run.py").string() + " > " +
                            (dir / "out.txt").string() + " 2>/dev/null";
    EXPECT_EQ(std::system(cmd.c_str()), 0);
    std::ifstream in(dir / "out.txt");
    std::set<std::uint32_t> out;
    std::uint32_t i = 0;
    while (in >> i) out.insert(i);
    std::filesystem::remove_all(dir);
    return out;
}

TEST(StatisticalOutliers, MatchesOpen3dExactly) {
    if (!open3d_available()) GTEST_SKIP() << "python3-open3d not installed";
    // A random bumpy surface with scattered outliers, no exact ties.
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::vector<Eigen::Vector3d> xyz;
    for (int i = 0; i < 4000; ++i) {
        const double x = uni(rng), y = uni(rng);
        xyz.emplace_back(x, y, 0.05 * std::sin(6 * x) * std::cos(4 * y) + 0.003 * uni(rng));
    }
    for (int i = 0; i < 60; ++i) xyz.emplace_back(uni(rng), uni(rng), 0.05 + 0.3 * uni(rng));
    for (double ratio : {2.0, 1.0, 0.5}) {
        PointCloud cloud = make_cloud(xyz);
        StatisticalOptions options;
        options.std_ratio = ratio;
        remove_statistical_outliers(cloud, options);
        std::ostringstream call;
        call << "remove_statistical_outlier(20, " << ratio << ")";
        EXPECT_EQ(kept(cloud), open3d_kept(xyz, call.str())) << "std_ratio " << ratio;
    }
    PointCloud cloud = make_cloud(xyz);
    RadiusOptions radius;
    radius.min_points = 16;
    radius.radius_m = 0.05;
    remove_radius_outliers(cloud, radius);
    EXPECT_EQ(kept(cloud), open3d_kept(xyz, "remove_radius_outlier(16, 0.05)"));
}

}  // namespace
}  // namespace rgbd::denoise
