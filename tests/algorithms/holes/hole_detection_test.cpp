#include "algorithms/holes/hole_detection.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <random>

#include "tests/algorithms/holes/hole_scenes.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {
namespace {

struct Hole {
    double x, y, r;
};

/// Jittered grid on the plane z = 0, spacing 2 mm, half-size `half`, with circular holes;
/// `noise` is the normal-direction noise in spacings.
SurfacePoints plane(double half, const std::vector<Hole>& holes, double noise = 0.0,
                    unsigned seed = 1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> jitter(-0.15 * kSpacing, 0.15 * kSpacing);
    std::normal_distribution<double> gauss(0.0, noise * kSpacing);
    SurfacePoints s;
    const int n = static_cast<int>(std::round(half / kSpacing));
    for (int i = -n; i <= n; ++i)
        for (int j = -n; j <= n; ++j) {
            const double x = i * kSpacing + jitter(rng), y = j * kSpacing + jitter(rng);
            bool inside = false;
            for (const Hole& h : holes) inside |= std::hypot(x - h.x, y - h.y) < h.r;
            if (inside) continue;
            s.position.emplace_back(x, y, noise > 0 ? gauss(rng) : 0.0);
        }
    return s;
}

/// Fibonacci sphere, radius 0.1 m, keeping points with polar angle >= cap_deg from +z.
SurfacePoints sphere(int n, double cap_deg = 0.0) {
    SurfacePoints s;
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n;
        const double r = std::sqrt(1.0 - z * z);
        if (std::acos(z) * 180.0 / M_PI < cap_deg) continue;
        s.position.emplace_back(0.1 * r * std::cos(golden * i), 0.1 * r * std::sin(golden * i),
                                0.1 * z);
    }
    return s;
}

/// Distance from (x, y) to the nearest hole rim or the outer border of the plane.
double rim_distance(const Eigen::Vector3d& p, double half, const std::vector<Hole>& holes) {
    double d = half - std::max(std::abs(p.x()), std::abs(p.y()));
    for (const Hole& h : holes) d = std::min(d, std::hypot(p.x() - h.x, p.y() - h.y) - h.r);
    return d;
}

struct Rates {
    double recall, false_rate;
};

Rates rates(const SurfacePoints& s, const std::vector<std::uint8_t>& flags, double half,
            const std::vector<Hole>& holes) {
    std::size_t truth = 0, hit = 0, far = 0, false_hits = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
        const double d = rim_distance(s.position[i], half, holes);
        if (d < 0.5 * kSpacing) {
            ++truth;
            hit += flags[i];
        } else if (d > 3.0 * kSpacing) {
            ++far;
            false_hits += flags[i];
        }
    }
    return {double(hit) / truth, double(false_hits) / far};
}

TEST(HoleDetection, PlaneWithHolesFindsEveryRimAndClassifiesThem) {
    const double half = 0.15;
    const std::vector<Hole> holes = {
        {-0.07, -0.07, 5 * kSpacing}, {0.06, -0.06, 3 * kSpacing}, {0.0, 0.07, 20 * kSpacing}};
    const SurfacePoints s = plane(half, holes, 0.2);
    rgbd::Report report;
    const auto result = rgbd::holes::detect_boundaries(s, {}, BoundaryOptions{}, &report);
    EXPECT_NEAR(result.spacing_m, kSpacing, 0.2 * kSpacing);
    const Rates r = rates(s, result.boundary, half, holes);
    EXPECT_GE(r.recall, 0.95) << report.dump();
    EXPECT_LE(r.false_rate, 0.005) << report.dump();
    // Three holes plus the outer border; the two small holes are small, the rest large.
    ASSERT_EQ(result.loops.size(), 4u) << report.dump();
    int small = 0;
    for (const auto& loop : result.loops) {
        small += loop.small;
        EXPECT_EQ(loop.kind, HoleKind::kUnknown);  // no sensors given
        if (loop.small) {
            bool near_small_hole = false;
            for (int h = 0; h < 2; ++h)
                near_small_hole |= std::hypot(loop.centre.x() - holes[h].x,
                                              loop.centre.y() - holes[h].y) < kSpacing;
            EXPECT_TRUE(near_small_hole);
            EXPECT_GT(std::abs(loop.normal.z()), 0.95);
        }
    }
    EXPECT_EQ(small, 2);
}

TEST(HoleDetection, EveryCriterionAndTheCombinationOnANoisyPlane) {
    // F1 of each single criterion and of the combination (all with coherence, hysteresis and
    // loops) on a plane with 0.5 spacings of noise: the combination reaches 0.95.
    const double half = 0.1;
    const std::vector<Hole> holes = {{0.0, 0.0, 8 * kSpacing}};
    const SurfacePoints s = plane(half, holes, 0.5, 7);
    auto f1 = [&](const BoundaryOptions& o) {
        const auto result = rgbd::holes::detect_boundaries(s, {}, o);
        const Rates r = rates(s, result.boundary, half, holes);
        std::size_t flagged = 0, tp = 0;
        for (std::size_t i = 0; i < s.size(); ++i) {
            flagged += result.boundary[i];
            tp += result.boundary[i] && rim_distance(s.position[i], half, holes) < 1.5 * kSpacing;
        }
        const double precision = flagged ? double(tp) / flagged : 0.0;
        return 2 * precision * r.recall / (precision + r.recall);
    };
    BoundaryOptions angle, halfdisk, shape;
    angle.w_halfdisk = angle.w_shape = 0.0;
    halfdisk.w_angle = halfdisk.w_shape = 0.0;
    shape.w_angle = shape.w_halfdisk = 0.0;
    const double combined = f1(BoundaryOptions{});
    std::cout << "F1 angle " << f1(angle) << ", half-disk " << f1(halfdisk) << ", shape "
              << f1(shape) << ", combined " << combined << "\n";
    EXPECT_GE(combined, 0.95);
}

TEST(HoleDetection, ClosedSphereHasNoBoundary) {
    const SurfacePoints s = sphere(30000);
    const auto result = rgbd::holes::detect_boundaries(s, {}, BoundaryOptions{});
    std::size_t flagged = 0;
    for (auto b : result.boundary) flagged += b;
    EXPECT_LE(flagged, s.size() / 1000);
    EXPECT_TRUE(result.loops.empty());
}

TEST(HoleDetection, SphereWithCapCutAwayHasOneRim) {
    const SurfacePoints s = sphere(30000, 30.0);
    const auto result = rgbd::holes::detect_boundaries(s, {}, BoundaryOptions{});
    ASSERT_EQ(result.loops.size(), 1u);
    const auto& loop = result.loops[0];
    // Rim at polar angle 30 degrees: centre on the axis at z = 0.1 cos 30, normal along z.
    EXPECT_NEAR(loop.centre.z(), 0.1 * std::cos(M_PI / 6), 2 * kSpacing);
    EXPECT_NEAR(loop.centre.head<2>().norm(), 0.0, kSpacing);
    EXPECT_GT(loop.normal.z(), 0.99);
    EXPECT_NEAR(loop.diameter_m, 0.2 * std::sin(M_PI / 6), 3 * kSpacing);
    EXPECT_FALSE(loop.small);
    // Every point within half a spacing (in arc length) of the rim is flagged; none far away.
    const double spacing = result.spacing_m;
    std::size_t truth = 0, hit = 0, false_hits = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
        const double polar = std::acos(s.position[i].z() / 0.1);
        const double arc = 0.1 * (polar - M_PI / 6);
        if (arc < 0.5 * spacing) {
            ++truth;
            hit += result.boundary[i];
        } else if (arc > 3 * spacing) {
            false_hits += result.boundary[i];
        }
    }
    EXPECT_GE(double(hit) / truth, 0.95);
    EXPECT_EQ(false_hits, 0u);
}

TEST(HoleDetection, VisibilityTellsOpeningsFromOcclusions) {
    const std::vector<Hole> holes = {{0.0, 0.0, 6 * kSpacing}};
    SurfacePoints s = plane(0.05, holes);
    auto sensor_at = [](const Eigen::Vector3d& c) {
        SensorView v;
        v.world_from_sensor.translation() = c;
        return v;
    };
    auto hole_loop = [&](const SurfacePoints& pts, const std::vector<SensorView>& sensors) {
        const auto result = rgbd::holes::detect_boundaries(pts, sensors, BoundaryOptions{});
        for (const auto& loop : result.loops)
            if (loop.centre.head<2>().norm() < kSpacing) return loop;
        ADD_FAILURE() << "no loop around the hole";
        return rgbd::holes::BoundaryLoop{};
    };
    // A sensor 1 m above the hole looked through it: a real opening.
    EXPECT_EQ(hole_loop(s, {sensor_at({0.0, 0.0, 1.0})}).kind, HoleKind::kOpening);
    // Seen only at grazing incidence (80 degrees off the normal): could not have seen it.
    EXPECT_EQ(hole_loop(s, {sensor_at({std::sin(1.4), 0.0, std::cos(1.4)})}).kind,
              HoleKind::kOcclusion);
    // An occluder (a 4 x 4 cm patch 10 cm above the hole) hides the hole from the sensor.
    SurfacePoints occluded = s;
    for (double x = -0.02; x <= 0.02; x += kSpacing)
        for (double y = -0.02; y <= 0.02; y += kSpacing) occluded.position.emplace_back(x, y, 0.1);
    const auto loop = hole_loop(occluded, {sensor_at({0.0, 0.0, 1.0})});
    EXPECT_EQ(loop.kind, HoleKind::kOcclusion);
    EXPECT_EQ(loop.seen_by, 0);
    // The sensor's frustum: a camera looking away from the hole cannot have seen it.
    SensorView away = sensor_at({0.0, 0.0, 1.0});  // optical axis +z: looks away from the plane
    away.intrinsics = rgbd::PinholeIntrinsics{512, 424, 365.5, 365.5, 256, 212, {}};
    EXPECT_EQ(hole_loop(s, {away}).kind, HoleKind::kOcclusion);
    SensorView towards = away;
    towards.world_from_sensor.linear() =
        Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
    EXPECT_EQ(hole_loop(s, {towards}).kind, HoleKind::kOpening);
}

TEST(SurfaceGradient, NormalsFramesAndColourGradientOnARamp) {
    SurfacePoints s = plane(0.05, {}, 0.0);
    // Tilt the plane about x by 30 degrees and colour it with a ramp along the plane's own y.
    const Eigen::Matrix3d tilt = Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitX()).matrix();
    for (auto& p : s.position) {
        const double y = p.y();
        p = tilt * p;
        const auto level = static_cast<std::uint8_t>(std::clamp(128.0 + 4000.0 * y, 0.0, 255.0));
        s.color.push_back({level, level, level});
    }
    const auto g = rgbd::holes::compute_surface_gradient(s, kSpacing, {}, {});
    const Eigen::Vector3d truth_normal = tilt * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d truth_dir = tilt * Eigen::Vector3d::UnitY();
    double worst_normal = 0, worst_dir = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
        if (s.position[i].norm() > 0.03) continue;  // away from the border and the clamp
        worst_normal = std::max(worst_normal,
                                std::acos(std::min(1.0, std::abs(g.normal[i].dot(truth_normal)))));
        worst_dir = std::max(
            worst_dir, std::acos(std::min(1.0, g.color_gradient[i].normalized().dot(truth_dir))));
        EXPECT_NEAR(g.e1[i].dot(g.normal[i]), 0.0, 1e-9);
        EXPECT_NEAR(g.e2[i].dot(g.e1[i]), 0.0, 1e-9);
        EXPECT_NEAR(g.e1[i].cross(g.e2[i]).dot(g.normal[i]), 1.0, 1e-9);
        EXPECT_LT(g.variation[i], 1e-3);
    }
    EXPECT_LT(worst_normal * 180 / M_PI, 1.0);
    EXPECT_LT(worst_dir * 180 / M_PI, 5.0);
}

TEST(HoleDetection, SameResultForOneAndManyThreads) {
    const SurfacePoints s = plane(0.06, {{0.0, 0.0, 6 * kSpacing}}, 0.3, 3);
    std::vector<float> p1;
    {
        tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
        p1 = rgbd::holes::detect_boundaries(s, {}, BoundaryOptions{}).probability;
    }
    const auto pn = rgbd::holes::detect_boundaries(s, {}, BoundaryOptions{}).probability;
    EXPECT_EQ(p1, pn);
}

// Six overlapping "frames" of the plane with three holes (a merged sequence: six times the
// density of one): thinned to a one-frame budget, every kept point is a measured one with its
// own view and colour, every input point has a kept point within a voxel diagonal, and the
// detection on the thinned set finds the same rims as on one frame.
TEST(ThinPoints, AMergedSequenceThinnedKeepsMeasuredPointsAndItsHoles) {
    const double half = 0.15;
    const std::vector<Hole> holes = {
        {-0.07, -0.07, 5 * kSpacing}, {0.06, -0.06, 3 * kSpacing}, {0.0, 0.07, 20 * kSpacing}};
    SurfacePoints merged;
    std::size_t one_frame = 0;
    for (int copy = 0; copy < 6; ++copy) {
        const SurfacePoints s = plane(half, holes, 0.2, 10 + copy);
        one_frame = s.size();
        for (const auto& p : s.position) {
            merged.position.push_back(p);
            merged.normal.emplace_back(0.0, 0.0, 1.0);
            merged.color.push_back({static_cast<std::uint8_t>(40 * copy), 0, 0});
            merged.view.push_back(copy);
        }
    }
    const std::size_t budget = one_frame + one_frame / 5;
    double voxel = -1.0;
    const SurfacePoints thin = rgbd::holes::thin_points(merged, budget, &voxel);
    ASSERT_LE(thin.size(), budget);
    EXPECT_GE(thin.size(), budget * 7 / 10);
    EXPECT_GT(voxel, kSpacing);
    ASSERT_EQ(thin.normal.size(), thin.size());
    ASSERT_EQ(thin.color.size(), thin.size());
    ASSERT_EQ(thin.view.size(), thin.size());

    std::map<std::array<double, 3>, std::size_t> index;
    for (std::size_t i = 0; i < merged.size(); ++i)
        index[{merged.position[i].x(), merged.position[i].y(), merged.position[i].z()}] = i;
    std::map<std::array<long, 2>, std::vector<std::size_t>> cells;  // kept points by voxel column
    for (std::size_t i = 0; i < thin.size(); ++i) {
        const auto& p = thin.position[i];
        const auto found = index.find({p.x(), p.y(), p.z()});
        ASSERT_NE(found, index.end()) << "kept point " << i << " is not a measured point";
        EXPECT_EQ(thin.view[i], merged.view[found->second]);
        EXPECT_EQ(thin.color[i].r, merged.color[found->second].r);
        cells[{std::lround(std::floor(p.x() / voxel)), std::lround(std::floor(p.y() / voxel))}]
            .push_back(i);
    }
    const double reach = voxel * std::sqrt(3.0);
    for (std::size_t i = 0; i < merged.size(); i += 7) {
        const auto& p = merged.position[i];
        const long cx = std::lround(std::floor(p.x() / voxel));
        const long cy = std::lround(std::floor(p.y() / voxel));
        double nearest = std::numeric_limits<double>::infinity();
        for (long dx = -2; dx <= 2; ++dx)
            for (long dy = -2; dy <= 2; ++dy) {
                const auto cell = cells.find({cx + dx, cy + dy});
                if (cell == cells.end()) continue;
                for (const std::size_t k : cell->second)
                    nearest = std::min(nearest, (thin.position[k] - p).norm());
            }
        ASSERT_LE(nearest, reach) << "input point " << i << " has no kept point near it";
    }

    rgbd::Report report;
    const auto result = rgbd::holes::detect_boundaries(thin, {}, BoundaryOptions{}, &report);
    // The same rims as one frame: three holes plus the outer border, the two small ones small.
    ASSERT_EQ(result.loops.size(), 4u) << report.dump();
    int small = 0;
    for (const auto& loop : result.loops) small += loop.small;
    EXPECT_EQ(small, 2);

    // Within the budget: returned as they are.
    double none = -1.0;
    const SurfacePoints same = rgbd::holes::thin_points(merged, merged.size(), &none);
    EXPECT_EQ(none, 0.0);
    EXPECT_EQ(same.position, merged.position);
    // Deterministic for any thread count.
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    EXPECT_EQ(rgbd::holes::thin_points(merged, budget).position, thin.position);
    SurfacePoints nan = merged;
    nan.position[3].y() = std::nan("");
    EXPECT_THROW(rgbd::holes::thin_points(nan, budget), rgbd::Error);
}

TEST(HoleDetection, RejectsBadInputAndAbsurdOptions) {
    SurfacePoints few;
    few.position = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    EXPECT_THROW(rgbd::holes::detect_boundaries(few, {}, {}), rgbd::InputError);
    SurfacePoints nan = plane(0.01, {});
    nan.position[5].x() = std::nan("");
    EXPECT_THROW(rgbd::holes::detect_boundaries(nan, {}, {}), rgbd::InputError);
    BoundaryOptions o;
    o.threshold = 0.0;
    EXPECT_THROW(o.check(), rgbd::InputError);
    o = {};
    o.neighbourhood.k = 1;
    EXPECT_THROW(o.check(), rgbd::InputError);
    o = {};
    o.w_angle = o.w_halfdisk = o.w_shape = 0.0;
    EXPECT_THROW(o.check(), rgbd::InputError);
    o = {};
    o.visible_max_angle_deg = 95;
    EXPECT_THROW(o.check(), rgbd::InputError);
}

}  // namespace
}  // namespace rgbd::holes
