// Tests of the adaptive density-based filter (docs/algorithms.md §8): two aligned views of a plane
// with floating clusters and sparse outliers, the sensors and local references, mark ==
// delete, errors, empty views, thread-count determinism, super-resolved points and their parents.
#include "algorithms/denoise/density_outliers.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <limits>
#include <random>

#include "algorithms/sampling/robust_spacing.hpp"
#include "tests/support/options_check.hpp"
#include "tests/support/pinhole.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {
namespace {

using test::rejects;

constexpr int kW = 128, kH = 96;

PinholeIntrinsics intrinsics() { return test::centred_pinhole(kW, kH, 180.0); }

/// The flag that marks the planted noise points (the truth of these tests).
constexpr const char* kPlanted = "planted";

/// View of the plane z = 1.5 (world) from a camera at `x` looking along +z; noise points
/// (flag kPlanted = 1) appended.
PointCloud plane_view(int id, double x, std::size_t clusters, std::size_t outliers,
                      std::uint64_t seed) {
    PointCloud view;
    view.view.id = id;
    view.view.sensor = "cam" + std::to_string(id);
    view.view.frame = ViewFrame::kWorld;
    view.view.intrinsics = intrinsics();
    Pose pose = Pose::Identity();
    pose.translation() = Eigen::Vector3d(x, 0.0, 0.0);
    view.view.world_from_sensor = pose;
    auto truth = view.add_flag(kPlanted);
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0.0, 0.0014);
    const auto k = intrinsics();
    for (int row = 0; row < kH; ++row)
        for (int col = 0; col < kW; ++col) {
            const Eigen::Vector3d p = pose * k.unproject(col, row, 1.5 + noise(rng));
            view.points.insert(to_point(p));
        }
    std::uniform_real_distribution<double> u(-0.3, 0.3), depth(0.6, 1.45);
    for (std::size_t c = 0; c < clusters; ++c) {
        // Floating 5-11 cm in front of the plane: farther than the cluster link distance (3 x
        // the 8 mm spacing of one view), so detached.
        const Eigen::Vector3d centre(u(rng), u(rng) * 0.6, 1.5 - 0.05 - 0.02 * double(c % 4));
        std::normal_distribution<double> spread(0.0, 0.004);
        for (int j = 0; j < 8; ++j) {
            auto idx = *view.points.insert(
                to_point(centre + Eigen::Vector3d(spread(rng), spread(rng), spread(rng))));
            truth[idx] = 1;
        }
    }
    for (std::size_t o = 0; o < outliers; ++o) {
        const double z = depth(rng);
        auto idx = *view.points.insert(to_point(Eigen::Vector3d(u(rng) * z, u(rng) * z, z)));
        truth[idx] = 1;
    }
    return view;
}

/// The report of remove_density_outliers (default options) on `views`, cleaned in place, and
/// the shares of the planted noise and of the surface (truth: the kPlanted flag) it removed.
struct Cleaned {
    Report report;
    double noise_removed = 0.0, surface_removed = 0.0;
};

Cleaned clean(std::vector<PointCloud>& views) {
    std::size_t noise = 0, surface = 0, noise_left = 0, surface_left = 0;
    for (const auto& v : views)
        for (auto idx : v.points) ((*v.flag(kPlanted))[idx] ? noise : surface)++;
    Cleaned c;
    c.report = remove_density_outliers(views, DensityOptions{});
    for (const auto& v : views)
        for (auto idx : v.points) ((*v.flag(kPlanted))[idx] ? noise_left : surface_left)++;
    c.noise_removed = 1.0 - double(noise_left) / double(noise);
    c.surface_removed = 1.0 - double(surface_left) / double(surface);
    return c;
}

std::vector<PointCloud> scene() {
    return {plane_view(0, 0.0, 10, 60, 1), plane_view(1, 0.25, 10, 60, 2)};
}

TEST(DensityOutliers, SensorsReferenceRemovesClustersAndOutliers) {
    auto views = scene();
    const Cleaned c = clean(views);
    EXPECT_EQ(c.report["reference"], "sensors");
    EXPECT_GE(c.noise_removed, 0.95) << c.report.dump();
    EXPECT_LE(c.surface_removed, 0.01) << c.report.dump();
    EXPECT_EQ(views[0].view.id, 0);
    EXPECT_EQ(views[1].view.id, 1);
}

TEST(DensityOutliers, LocalReferenceWithoutCameras) {
    auto views = scene();
    for (auto& v : views) v.view.intrinsics.reset();
    const Cleaned c = clean(views);
    EXPECT_EQ(c.report["reference"], "local");
    EXPECT_GE(c.noise_removed, 0.9) << c.report.dump();
    EXPECT_LE(c.surface_removed, 0.01) << c.report.dump();
    DensityOptions sensors;
    sensors.reference = DensityReference::kSensors;
    EXPECT_THROW(remove_density_outliers(views, sensors), InputError);
}

TEST(DensityOutliers, MarkEqualsDelete) {
    const auto before = scene();
    auto deleted = before, marked = before;
    DensityOptions o;
    remove_density_outliers(deleted, o);
    o.mark = true;
    remove_density_outliers(marked, o);
    for (std::size_t v = 0; v < before.size(); ++v) {
        ASSERT_EQ(marked[v].size(), before[v].size());
        std::vector<Point_3> a, b;
        for (auto idx : deleted[v].points) a.push_back(deleted[v].points.point(idx));
        const auto noise = *marked[v].flag(prop::kNoise);
        for (auto idx : marked[v].points)
            if (!noise[idx]) b.push_back(marked[v].points.point(idx));
        EXPECT_EQ(a, b);
    }
}

TEST(DensityOutliers, ErrorsAndEmptyViews) {
    auto views = scene();
    views[1].points.insert(Point_3(std::numeric_limits<double>::quiet_NaN(), 0, 1));
    EXPECT_THROW(remove_density_outliers(views, DensityOptions{}), InputError);
    views = scene();
    views[0].view.frame = ViewFrame::kSensor;
    views[0].view.world_from_sensor.reset();
    EXPECT_THROW(remove_density_outliers(views, DensityOptions{}), InputError);

    std::vector<PointCloud> empty(2);
    EXPECT_EQ(remove_density_outliers(empty, DensityOptions{})["removed"].get<int>(), 0);
    std::vector<PointCloud> none;
    EXPECT_EQ(remove_density_outliers(none, DensityOptions{})["removed"].get<int>(), 0);

    EXPECT_TRUE(rejects<DensityOptions>([](auto& o) { o.beta = -1; }));
    EXPECT_TRUE(rejects<DensityOptions>([](auto& o) { o.k = 1; }));
}

TEST(DensityOutliers, OneAndTwoThreadsAgree) {
    auto one = scene(), two = scene();
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        remove_density_outliers(one, DensityOptions{});
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
        remove_density_outliers(two, DensityOptions{});
    }
    for (std::size_t v = 0; v < one.size(); ++v) {
        ASSERT_EQ(one[v].size(), two[v].size());
        auto a = one[v].points.begin();
        for (auto b : two[v].points) EXPECT_EQ(one[v].points.point(*a++), two[v].points.point(b));
    }
}

/// spacing_m (found on a cell grid, with isolated queries capped) must be exactly the lower
/// median over the views of sampling::robust_spacing(view, 2000, seed), the kd-tree estimate:
/// on the plane scene (0.5 % isolated outliers), on views that are mostly isolated points
/// (the cap cannot settle the median: full search), and on collinear points (flat box).
TEST(DensityOutliers, SpacingIsTheViewsRobustSpacing) {
    const auto expect_spacing = [](std::vector<PointCloud> views, const std::string& what) {
        std::vector<double> s;
        for (const auto& v : views) {
            std::vector<Eigen::Vector3d> xyz;
            for (auto idx : v.points) xyz.push_back(to_eigen(v.points.point(idx)));
            s.push_back(sampling::robust_spacing(xyz, 2000, 42));
        }
        std::sort(s.begin(), s.end());
        DensityOptions o;
        o.mark = true;
        const Report r = remove_density_outliers(views, o);
        EXPECT_EQ(r["spacing_m"].get<double>(), s[(s.size() - 1) / 2]) << what;
    };
    expect_spacing(scene(), "plane scene");
    std::vector<PointCloud> sparse = scene();
    for (auto& v : sparse) {
        std::mt19937_64 rng(7 + std::uint64_t(v.view.id));
        std::uniform_real_distribution<double> u(-2.0, 2.0);
        PointSet kept;
        std::size_t i = 0;
        for (auto idx : v.points)  // keep 1 in 40 plane points, then many scattered ones
            if (i++ % 40 == 0) kept.insert(v.points.point(idx));
        for (int j = 0; j < 3000; ++j) kept.insert(Point_3(u(rng), u(rng), 1.5 + u(rng)));
        v.points = kept;
    }
    expect_spacing(sparse, "mostly isolated points");
    std::vector<PointCloud> line = scene();
    for (auto& v : line) {
        PointSet pts;
        for (int j = 0; j < 5000; ++j) pts.insert(Point_3(0.001 * j + 0.0003 * (j % 7), 0.0, 1.5));
        v.points = pts;
    }
    expect_spacing(line, "collinear points");
}

/// View of the plane z = 1.5 from a camera at (-1, 0, 1.32) aiming at (0.1, 0, 1.5): its rays
/// meet the plane at 61-90 degrees of incidence (about 81 at the scene's centre), steeper than
/// theta_max = 75 where they cross the middle of the plane. Normals (0, 0, -1).
PointCloud grazing_view(int id, std::uint64_t seed) {
    PointCloud view;
    view.view.id = id;
    view.view.sensor = "cam" + std::to_string(id);
    view.view.frame = ViewFrame::kWorld;
    view.view.intrinsics = intrinsics();
    const Eigen::Vector3d centre(-1.0, 0.0, 1.32), target(0.1, 0.0, 1.5);
    const Eigen::Vector3d z = (target - centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    Pose pose = Pose::Identity();
    pose.linear().col(0) = x;
    pose.linear().col(1) = z.cross(x);
    pose.linear().col(2) = z;
    pose.translation() = centre;
    view.view.world_from_sensor = pose;
    view.points.add_normal_map();
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> noise(0.0, 0.0014);
    const auto k = intrinsics();
    for (int row = 0; row < kH; ++row)
        for (int col = 0; col < kW; ++col) {
            const Eigen::Vector3d ray = pose.linear() * k.unproject(col, row, 1.0);
            if (ray.z() <= 1e-6) continue;
            const Eigen::Vector3d hit = centre + ray * ((1.5 - centre.z()) / ray.z());
            if (std::abs(hit.x()) > 0.6 || std::abs(hit.y()) > 0.45) continue;
            view.points.insert(to_point(hit + ray.normalized() * noise(rng)),
                               Vector_3(0.0, 0.0, -1.0));
        }
    return view;
}

/// The consensus test on a known answer. The plane z = 1.5 seen frontally by two views (x = 0
/// and 0.25) and at a grazing angle by a third, every point with the normal (0, 0, -1) (as
/// rgbd-align's per-view normals). Off-surface points d = 0.85 r in front of the plane (r =
/// the counting radius: measured / expected ~ 1 - 0.85^2 = 0.28, above beta = 0.1, so the
/// density test keeps them; below consensus_ratio = 0.5; d ~ 13 sigma_z), 2.5 r apart:
/// - 30 appended to the grazing view (its ray meets their normal at ~82 degrees, steeper than
///   theta_max: a flying pixel at a depth discontinuity) must all be flagged;
/// - 20 appended to a frontal view (seen at ~3 degrees: a real detail for all we know) must stay;
/// - no surface point may go. Without the test (consensus_ratio 0), or with a distance
///   threshold above d (consensus_sigmas 30), the flying points stay: all three cues count.
TEST(DensityOutliers, ConsensusFlagsSteepOffSurfacePoints) {
    auto with_normals = [](PointCloud v) {
        v.points.add_normal_map();
        for (auto idx : v.points) v.points.normal(idx) = Vector_3(0.0, 0.0, -1.0);
        return v;
    };
    const std::vector<PointCloud> surface = {with_normals(plane_view(0, 0.0, 0, 0, 1)),
                                             with_normals(plane_view(1, 0.25, 0, 0, 2)),
                                             grazing_view(2, 3)};
    DensityOptions o;
    o.mark = true;
    auto probe = surface;
    const double r = remove_density_outliers(probe, o)["radius_m"].get<double>();
    ASSERT_GT(r, 0.01);
    ASSERT_LT(r, 0.04);
    auto views = surface;
    const double d = 0.85 * r;
    std::vector<std::size_t> first = {views[2].size(), views[0].size()};
    for (double x = -0.15; x <= 0.4; x += 2.5 * r) {
        for (const double y : {-0.15, 0.0, 0.15})
            views[2].points.insert(Point_3(x, y, 1.5 - d), Vector_3(0.0, 0.0, -1.0));
        for (const double y : {-0.075, 0.075})
            views[0].points.insert(Point_3(x, y, 1.5 - d), Vector_3(0.0, 0.0, -1.0));
    }
    const std::size_t steep = views[2].size() - first[0], frontal = views[0].size() - first[1];
    ASSERT_GE(steep, 24u);
    ASSERT_GE(frontal, 16u);
    const auto run = [&](const DensityOptions& options, std::size_t& steep_marked,
                         std::size_t& frontal_marked, std::size_t& surface_marked) {
        auto v = views;
        const Report report = remove_density_outliers(v, options);
        steep_marked = frontal_marked = surface_marked = 0;
        for (std::size_t s = 0; s < v.size(); ++s) {
            const auto noise = *v[s].flag(prop::kNoise);
            std::size_t i = 0;
            for (auto idx : v[s].points) {
                const bool added = (s == 2 && i >= first[0]) || (s == 0 && i >= first[1]);
                ++i;
                if (!noise[idx]) continue;
                if (!added)
                    ++surface_marked;
                else
                    ++(s == 2 ? steep_marked : frontal_marked);
            }
        }
        return report;
    };
    std::size_t steep_marked = 0, frontal_marked = 0, surface_marked = 0;
    Report report = run(o, steep_marked, frontal_marked, surface_marked);
    EXPECT_EQ(steep_marked, steep) << report.dump();
    EXPECT_EQ(frontal_marked, 0u) << report.dump();
    EXPECT_EQ(surface_marked, 0u) << report.dump();
    EXPECT_EQ(report["consensus"].get<std::size_t>(), steep) << report.dump();
    EXPECT_EQ(report["density"].get<std::size_t>(), 0u) << report.dump();

    DensityOptions off = o;
    off.consensus_ratio = 0.0;
    report = run(off, steep_marked, frontal_marked, surface_marked);
    EXPECT_EQ(steep_marked, 0u) << report.dump();
    DensityOptions far = o;
    far.consensus_sigmas = 30.0;
    report = run(far, steep_marked, frontal_marked, surface_marked);
    EXPECT_EQ(steep_marked, 0u) << report.dump();

    EXPECT_TRUE(rejects<DensityOptions>([](auto& o) { o.consensus_ratio = 1.5; }));
    EXPECT_TRUE(rejects<DensityOptions>([](auto& o) { o.consensus_radius = 2.5; }));
    EXPECT_TRUE(rejects<DensityOptions>([](auto& o) { o.consensus_sigmas = 0.0; }));
}

/// The plane scene with a pixel map and, in both views, the 8 super-resolved children of every
/// point (flagged synthetic, carrying their parent's pixel) a third of a depth pixel apart, as an
/// 8-neighbour upsampling makes them: the planted clusters' and outliers' children are planted
/// too. Appended last to view 0: one bad child of a surface point, 6 cm in front of the plane
/// (planted).
std::vector<PointCloud> upsampled_scene() {
    std::vector<PointCloud> views = scene();
    const double third = 1.5 / intrinsics().fx / 3.0;  // a third of the plane's pixel footprint
    for (auto& v : views) {
        auto pixel = v.add_pixel_map();
        std::uint32_t i = 0;
        for (auto idx : v.points) pixel[idx] = i++;
        v.view.grid_width = kW;
        v.view.grid_height = kH + 64;  // room for the appended noise points' pixels
        auto synthetic = v.add_flag(prop::kSynthetic);
        auto planted = *v.flag(kPlanted);
        const std::vector<PointSet::Index> parents(v.points.begin(), v.points.end());
        for (const auto parent : parents)
            for (int dx = -1; dx <= 1; ++dx)
                for (int dy = -1; dy <= 1; ++dy) {
                    if (dx == 0 && dy == 0) continue;
                    const auto idx = *v.points.insert(to_point(to_eigen(v.points.point(parent)) +
                                                               third * Eigen::Vector3d(dx, dy, 0)));
                    synthetic[idx] = 1;
                    planted[idx] = planted[parent];
                    pixel[idx] = pixel[parent];
                }
    }
    PointCloud& v = views[0];
    const auto bad = *v.points.insert(Point_3(0.0, 0.0, 1.44));
    (*v.flag(prop::kSynthetic))[bad] = 1;
    (*v.flag(kPlanted))[bad] = 1;
    (*v.pixel_map())[bad] = std::uint32_t(kH / 2) * kW + kW / 2;
    return views;
}

// Super-resolved points (flagged synthetic) are counted in the neighbourhoods and judged on their
// own count against the expected density of the measured point they were made from (the one
// with their pixel), and take its verdict in the cluster pass, which links the measured points
// only: the planted clusters go with their children, a child 6 cm off the surface goes on its own
// (its count is far below its parent's expected density), no surface child goes. With
// judge_synthetic every point is judged alike (the children link the clusters too).
TEST(DensityOutliers, SuperResolvedPointsFollowTheirParents) {
    for (const bool judge_synthetic : {false, true}) {
        std::vector<PointCloud> views = upsampled_scene();
        DensityOptions o;
        o.judge_synthetic = judge_synthetic;
        o.mark = true;
        const Report report = remove_density_outliers(views, o);
        std::size_t planted = 0, planted_marked = 0, surface_marked = 0, children = 0;
        for (const auto& v : views) {
            const auto noise = *v.flag(prop::kNoise);
            const auto truth = *v.flag(kPlanted);
            const auto synthetic = v.flag(prop::kSynthetic);
            for (auto idx : v.points) {
                children += synthetic && (*synthetic)[idx];
                planted += truth[idx];
                planted_marked += truth[idx] && noise[idx];
                surface_marked += !truth[idx] && noise[idx];
            }
        }
        const std::string what =
            std::string(judge_synthetic ? "judged alike: " : "followers: ") + report.dump();
        EXPECT_EQ(report.contains("synthetic_followers"), !judge_synthetic) << what;
        if (!judge_synthetic) EXPECT_EQ(report["synthetic_followers"], children) << what;
        EXPECT_GE(double(planted_marked), 0.95 * double(planted)) << what;
        EXPECT_LE(double(surface_marked), 0.01 * double(children)) << what;
        // The bad child, last of view 0.
        const PointCloud& v0 = views[0];
        const auto last = *std::prev(v0.points.end());
        EXPECT_EQ((*v0.flag(prop::kNoise))[last], 1) << what;
    }
}

}  // namespace
}  // namespace rgbd::denoise
