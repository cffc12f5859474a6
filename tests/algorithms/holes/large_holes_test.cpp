// Large holes (§12) and the head top (§13) on surfaces with a known answer: an ellipsoid head
// seen by a level ring of sensors (the crown is missing by construction) and an egg-shaped body
// with a 6 x 4 cm patch cut from its side and an open bottom cut; the body axis from a sensor
// ring and from the points alone; bad input.
#include "algorithms/holes/large_holes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <random>

#include "tests/algorithms/holes/hole_scenes.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {
namespace {

Eigen::Vector3d outward(const Eigen::Vector3d& axes, const Eigen::Vector3d& p) {
    return p.cwiseQuotient(axes.cwiseProduct(axes)).normalized();
}

/// Ellipsoid samples about `spacing` apart (Fibonacci sphere mapped to the ellipsoid, count
/// from the area), with `keep` deciding per point (position, outward normal).
template <class Keep>
std::vector<Eigen::Vector3d> sample(const Eigen::Vector3d& axes, double spacing, Keep keep,
                                    double noise_m = 0, unsigned seed = 3) {
    const double p = 1.6;
    const double area =
        4 * M_PI *
        std::pow((std::pow(axes.x() * axes.y(), p) + std::pow(axes.x() * axes.z(), p) +
                  std::pow(axes.y() * axes.z(), p)) /
                     3,
                 1 / p);
    // The mapping stretches the sphere unevenly: oversample by the largest axis ratio.
    const int n =
        static_cast<int>(area / (spacing * spacing) * 1.15 * (axes.maxCoeff() / axes.minCoeff()));
    std::mt19937 rng(seed);
    std::normal_distribution<double> gauss(0.0, noise_m > 0 ? noise_m : 1.0);
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    std::vector<Eigen::Vector3d> out;
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n;
        const double r = std::sqrt(1.0 - z * z);
        Eigen::Vector3d q = Eigen::Vector3d(r * std::cos(golden * i), r * std::sin(golden * i), z)
                                .cwiseProduct(axes);
        const Eigen::Vector3d nrm = outward(axes, q);
        if (!keep(q, nrm)) continue;
        if (noise_m > 0) q += gauss(rng) * nrm;
        out.push_back(q);
    }
    return out;
}

SurfacePoints with_normals(const std::vector<Eigen::Vector3d>& xyz, const Eigen::Vector3d& axes,
                           std::vector<Eigen::Vector3d>& normals) {
    SurfacePoints s;
    s.position = xyz;
    normals.clear();
    for (const auto& p : xyz) {
        normals.push_back(outward(axes, p));
        s.color.push_back({static_cast<std::uint8_t>(100 + 80 * (p.z() > 0)), 120, 140});
    }
    return s;
}

/// Eight sensors on a level ring of radius 1.5 m at height `z`, looking at the z axis (camera:
/// z forward, y down).
std::vector<SensorView> ring(double z) {
    std::vector<SensorView> out;
    for (int k = 0; k < 8; ++k) {
        const double a = 2 * M_PI * k / 8;
        const Eigen::Vector3d c(1.5 * std::cos(a), 1.5 * std::sin(a), z);
        out.push_back(look_at(c, Eigen::Vector3d(0, 0, z)));
    }
    return out;
}

/// The §12 test body: an egg 12 x 10 cm wide and 25 cm tall, open below z = -0.15 m.
const Eigen::Vector3d kEggAxes(0.12, 0.10, 0.25);

/// Whether q lies in the 6 x 4 cm patch cut from the egg's side (centred at azimuth 0.6 rad,
/// z = 0.02 m; arc length at the egg's mean radius 0.11 m), grown by `margin` metres.
bool in_side_patch(const Eigen::Vector3d& q, double margin = 0) {
    const double arc = std::remainder(std::atan2(q.y(), q.x()) - 0.6, 2 * M_PI) * 0.11;
    return std::abs(arc) < 0.03 + margin && std::abs(q.z() - 0.02) < 0.02 + margin;
}

/// Samples of the egg without its side patch, with `noise_m` normal noise.
std::vector<Eigen::Vector3d> egg_without_patch(double noise_m) {
    return sample(
        kEggAxes, kSpacing,
        [](const auto& q, const auto&) { return q.z() > -0.15 && !in_side_patch(q); }, noise_m);
}

/// Mean nearest distance from each of `a` to `b` (brute force; small sets).
double mean_nearest(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
    double sum = 0;
    for (const auto& p : a) {
        double best = std::numeric_limits<double>::infinity();
        for (const auto& q : b) best = std::min(best, (p - q).squaredNorm());
        sum += std::sqrt(best);
    }
    return sum / double(a.size());
}

TEST(BodyAxis, FromTheSensorRingPointsUp) {
    const Eigen::Vector3d axes(0.07, 0.08, 0.11);
    const auto xyz = sample(axes, 0.004, [](const auto&, const auto&) { return true; });
    std::vector<Eigen::Vector3d> normals;
    const SurfacePoints s = with_normals(xyz, axes, normals);
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(0.05));
    EXPECT_TRUE(axis.from_sensors);
    EXPECT_GT(axis.up.z(), std::cos(0.5 * M_PI / 180));
}

TEST(BodyAxis, WithoutSensorsTheNarrowEndIsUp) {
    // An egg: wide bottom half (x, y radii 0.12) under a narrow top half (0.07), 0.25 tall.
    std::vector<Eigen::Vector3d> xyz;
    for (const auto& p : sample(Eigen::Vector3d(0.12, 0.12, 0.25), 0.005,
                                [](const auto&q, const auto&) { return q.z() < 0; }))
        xyz.push_back(p);
    for (const auto& p : sample(Eigen::Vector3d(0.07, 0.07, 0.25), 0.005,
                                [](const auto&q, const auto&) { return q.z() >= 0; }))
        xyz.push_back(p);
    SurfacePoints s;
    s.position = xyz;
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, {});
    EXPECT_FALSE(axis.from_sensors);
    EXPECT_GT(axis.up.z(), 0.999);
}

// §13 test: ellipsoid head (semi-axes 7.5 x 8.5 cm, 11 cm tall), 0.3 mm noise, cut below the
// jaw (open bottom); a level ring at the top of the head never sees normals steeper than 35
// degrees from up: that crown is missing. Chamfer of the filled points to the true crown
// < 3 mm at a 2 mm spacing (docs/algorithms.md §13).
TEST(HeadTop, FillsTheCrownARingNeverSees) {
    const Eigen::Vector3d axes(0.075, 0.085, 0.11);
    const double crown_cos = std::cos(35 * M_PI / 180);
    const auto seen = [&](const Eigen::Vector3d& q, const Eigen::Vector3d& n) {
        return q.z() > -0.06 && n.z() < crown_cos;
    };
    const auto xyz = sample(axes, kSpacing, seen, 0.0003);
    std::vector<Eigen::Vector3d> normals;
    const SurfacePoints s = with_normals(xyz, axes, normals);
    const auto crown =
        sample(axes, kSpacing, [&](const auto&, const auto& n) { return n.z() >= crown_cos; });
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(0.11));
    ASSERT_TRUE(axis.from_sensors);
    rgbd::Report report;
    const auto added = rgbd::holes::fill_head_top(s, normals, axis, kSpacing, ring(0.11),
                                                  InpaintOptions{}, &report);
    ASSERT_GT(added.position.size(), crown.size() / 2);
    EXPECT_LT(report["head_top"]["ellipsoid_rms_spacings"].get<double>(), 0.5);
    double worst = 0;
    for (std::size_t i = 0; i < added.position.size(); ++i) {
        EXPECT_EQ(added.mechanism[i], FillMechanism::kHeadTop);
        worst = std::max(worst, ellipsoid_distance(axes, added.position[i]));
        // Normals from the height map point out of the head.
        EXPECT_GT(added.normal[i].dot(outward(axes, added.position[i])), 0.8);
    }
    const double to_truth = mean_nearest(added.position, crown);
    const double from_truth = mean_nearest(crown, added.position);
    const double chamfer = 0.5 * (to_truth + from_truth);
    std::cout << "head top: " << added.position.size() << " points for a crown of " << crown.size()
              << " samples; Chamfer " << chamfer * 1e3 << " mm (to truth " << to_truth * 1e3
              << ", from truth " << from_truth * 1e3 << "), max surface "
              << "distance " << worst * 1e3 << " mm; " << report.dump() << "\n";
    EXPECT_LT(chamfer, 0.003);
    EXPECT_LT(worst, 0.006);
    // No point below the top region (the open bottom is not the head top's business).
    for (const auto& p : added.position) EXPECT_GT(p.z(), 0.0);
}

/// A standing figure for §13: a head (semi-axes `axes`, centred at the origin) and, well below
/// it, a body (a cylinder of radius 15 cm from z = -1.6 to -0.3 m, sampled every 1 cm), so the
/// top region (12% of the height) reaches below the head's middle. `seen` says which head points
/// a sensor measured; the body is all seen. Normals outward.
SurfacePoints standing_figure(
    const Eigen::Vector3d& axes,
    const std::function<bool(const Eigen::Vector3d&, const Eigen::Vector3d&)>& seen,
    std::vector<Eigen::Vector3d>& normals) {
    SurfacePoints s;
    normals.clear();
    const auto add = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
        s.position.push_back(p);
        s.color.push_back({150, 120, 100});
        normals.push_back(n);
    };
    for (const auto& p : sample(axes, kSpacing, seen)) add(p, outward(axes, p));
    const auto cylinder = [&](double radius, double z0, double z1, double step) {
        const int around = static_cast<int>(2 * M_PI * radius / step);
        for (double z = z0; z < z1; z += step)
            for (int k = 0; k < around; ++k) {
                const double a = 2 * M_PI * k / around;
                const Eigen::Vector3d n(std::cos(a), std::sin(a), 0);
                add(Eigen::Vector3d(radius * n.x(), radius * n.y(), z), n);
            }
    };
    cylinder(0.15, -1.6, -0.3, 0.01);
    return s;
}

// §13 on a standing figure whose head is above the ring (sensors at z = -0.35 m, 1.5 m away):
// they see the chin and the jaw from below and nothing of the head more than ~80 degrees from
// up. The top-down height map took the chin seen from below as the top of its columns, and the
// crown was pulled down to it (a 1.4 m man on a floor, issue 35: 58-71% of the head-top points
// farther than 5 mm from the truth, up to 55 mm). A column whose highest point faces down has
// the body above it: its top was not seen (top_min_up). Every new point lies within 5 mm of the
// head; with every column taken as seen (the dissertation's map), the crown is left open.
TEST(HeadTop, AStandingFiguresCrownAboveTheRingIsNotTakenFromTheChin) {
    const Eigen::Vector3d axes(0.075, 0.085, 0.11);
    std::vector<Eigen::Vector3d> normals;
    const SurfacePoints s = standing_figure(
        axes, [](const auto&, const Eigen::Vector3d& n) { return n.z() < 0.2; }, normals);
    const auto crown =
        sample(axes, kSpacing, [](const auto&, const auto& n) { return n.z() >= 0.2; });
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(-0.35));
    ASSERT_TRUE(axis.from_sensors);
    const auto fill = [&](const InpaintOptions& options, rgbd::Report* report) {
        return rgbd::holes::fill_head_top(s, normals, axis, kSpacing, ring(-0.35), options, report);
    };
    const auto worst_of = [&](const FillResult& added) {
        double worst = 0;
        for (const auto& p : added.position) worst = std::max(worst, ellipsoid_distance(axes, p));
        return worst;
    };
    rgbd::Report report;
    const auto added = fill(InpaintOptions{}, &report);
    ASSERT_GT(added.position.size(), 100u) << report.dump();
    EXPECT_LT(mean_nearest(crown, added.position), 0.003) << "the crown is not covered";
    EXPECT_GT(report["head_top"]["top_points_facing_down"].get<int>(), 0) << report.dump();
    const double worst = worst_of(added);
    std::cout << "standing figure's crown: " << added.position.size() << " points, max distance "
              << worst * 1e3 << " mm; " << report.dump() << "\n";
    EXPECT_LT(worst, 0.005);
    // With every column taken as seen, the chin's columns hide the crown: nothing is filled
    // (here), or the crown is pulled down to the chin (the man).
    InpaintOptions every_column;
    every_column.top_min_up = -1;
    const auto old = fill(every_column, nullptr);
    EXPECT_TRUE(old.position.size() < 100 || worst_of(old) > 0.005);
}

/// A superquadric head (|x/a|^e + |y/b|^e + |z/c|^e = 1, e > 2: flatter on top than the
/// ellipsoid that §13 fits), as value F(p) - 1 and gradient.
struct Superquadric {
    Eigen::Vector3d axes;
    double e;
    double f(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d q = p.cwiseQuotient(axes).cwiseAbs();
        return std::pow(std::pow(q.x(), e) + std::pow(q.y(), e) + std::pow(q.z(), e), 1 / e);
    }
    Eigen::Vector3d gradient(const Eigen::Vector3d& p) const {
        const Eigen::Vector3d q = p.cwiseQuotient(axes);
        const double s = std::pow(f(p), 1 - e);
        Eigen::Vector3d g;
        for (int i = 0; i < 3; ++i)
            g[i] = s * std::pow(std::abs(q[i]), e - 1) * (q[i] < 0 ? -1 : 1) / axes[i];
        return g;
    }
    double distance(const Eigen::Vector3d& p) const {  // first order
        return std::abs(f(p) - 1) / gradient(p).norm();
    }
};

// §13 on a head that is no ellipsoid, measured with noise: a superquadric (e = 2.6, semi-axes
// 7.5 x 8.5 x 11 cm) sampled at 2 mm with 1 mm of noise along the normal (the sensors' noise
// at the grazing angles of the crown's rim), the crown beyond 35 degrees from up unseen. The
// fitted ellipsoid runs up to several mm off such a crown and the largest of several noisy
// heights per pixel sits above the surface; the crown follows the ellipsoid's shape moved onto
// the rim's smoothed residuals, so every new point lies within 3 mm of the true surface
// (the bound for the busts' crowns; measured: max 1.9 mm, mean 0.47 mm; with the ellipsoid
// blended into the inpainted heights over a rim band instead, max 3.2 mm, mean 1.0 mm).
TEST(HeadTop, ACrownThatIsNoEllipsoidFollowsTheRim) {
    const Superquadric head{Eigen::Vector3d(0.075, 0.085, 0.11), 2.6};
    const double crown_cos = std::cos(35 * M_PI / 180);
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, 0.001);
    std::vector<Eigen::Vector3d> xyz, normals;
    int crown = 0;
    const int n = 60000;
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
        const Eigen::Vector3d d(r * std::cos(golden * i), r * std::sin(golden * i), z);
        const Eigen::Vector3d p = d / head.f(d);  // radial projection onto the surface
        const Eigen::Vector3d nrm = head.gradient(p).normalized();
        if (p.z() <= -0.06) continue;
        if (nrm.z() >= crown_cos) {
            ++crown;
            continue;
        }
        xyz.push_back(p + noise(rng) * nrm);
        normals.push_back(nrm);
    }
    SurfacePoints s;
    s.position = xyz;
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(0.11));
    rgbd::Report report;
    const auto added = rgbd::holes::fill_head_top(s, normals, axis, kSpacing, ring(0.11),
                                                  InpaintOptions{}, &report);
    ASSERT_EQ(report["head_top"]["ellipsoid"], true) << report.dump();
    ASSERT_GT(added.position.size(), 200u) << report.dump();
    double worst = 0, sum = 0;
    for (const auto& p : added.position) {
        worst = std::max(worst, head.distance(p));
        sum += head.distance(p);
    }
    std::cout << "superquadric crown: " << added.position.size() << " points (" << crown
              << " crown samples), mean " << 1e3 * sum / double(added.position.size())
              << " mm, max " << worst * 1e3 << " mm from the surface; " << report.dump() << "\n";
    EXPECT_LT(worst, 0.003);
    EXPECT_LT(sum / double(added.position.size()), 0.001);
}

// §13 on a head whose side is a vertical wall standing on a wider ledge (shoulders, an ear, a
// collar): a cylinder 7 cm in radius whose flat top no sensor of the ring below sees, on a ledge
// out to 13 cm. The columns along the wall have their highest point on it, facing sideways, and
// the estimated normals scatter by a few degrees (here 4), so many of those tops face down by a
// hair. Taken as unseen tops (top_min_up 0), they made thin rings of hole pixels between the seen
// ledge and the seen side, inside the hull of the known pixels; on the standing man of the
// variety set (seed 2) the crown's surface was carried into such a strip along the side of the
// head above the ear: 2.5% of the head top's points 5-12 mm off the truth. A top facing down by
// less than the normals' scatter is a wall seen edge-on (top_min_up -0.1, 5.7 degrees), not a
// column whose top no sensor saw.
TEST(HeadTop, AWallSeenEdgeOnIsNotAnUnseenTop) {
    const double radius = 0.07, top = 0.05, ledge_z = -0.03, ledge_r = 0.13;
    std::mt19937 rng(11);
    std::normal_distribution<double> tilt(0.0, 4.0 * M_PI / 180);
    const auto scatter = [&](const Eigen::Vector3d& n) {
        const Eigen::Vector3d a = n.unitOrthogonal(), b = n.cross(a);
        return (n + tilt(rng) * a + tilt(rng) * b).normalized().eval();
    };
    SurfacePoints s;
    std::vector<Eigen::Vector3d> normals;
    const int around = static_cast<int>(2 * M_PI * radius / kSpacing);
    for (double z = ledge_z + kSpacing; z <= top + 1e-9; z += kSpacing)
        for (int k = 0; k < around; ++k) {
            const double a = 2 * M_PI * (k + 0.5 * (std::lround(z / kSpacing) % 2)) / around;
            const Eigen::Vector3d n(std::cos(a), std::sin(a), 0);
            s.position.push_back(radius * n + Eigen::Vector3d(0, 0, z));
            normals.push_back(scatter(n));
        }
    for (double x = -ledge_r; x <= ledge_r; x += kSpacing)
        for (double y = -ledge_r; y <= ledge_r; y += kSpacing) {
            if (std::hypot(x, y) <= radius + kSpacing || std::hypot(x, y) > ledge_r) continue;
            s.position.emplace_back(x, y, ledge_z);
            normals.push_back(scatter(Eigen::Vector3d::UnitZ()));
        }
    // The body below the ledge (its side, down to z = -0.2 m), so the top region (half the
    // height) holds the wall and the ledge.
    const int body_around = static_cast<int>(2 * M_PI * ledge_r / kSpacing);
    for (double z = -0.2; z < ledge_z - 0.5 * kSpacing; z += kSpacing)
        for (int k = 0; k < body_around; ++k) {
            const double a = 2 * M_PI * k / body_around;
            const Eigen::Vector3d n(std::cos(a), std::sin(a), 0);
            s.position.push_back(ledge_r * n + Eigen::Vector3d(0, 0, z));
            normals.push_back(scatter(n));
        }
    s.color.assign(s.position.size(), {150, 120, 100});
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(-0.35));
    ASSERT_TRUE(axis.from_sensors);
    const auto facing_down = [&](double top_min_up) {
        InpaintOptions options;
        options.top_min_up = top_min_up;
        options.top_fraction = 0.5;
        rgbd::Report report;
        rgbd::holes::fill_head_top(s, normals, axis, kSpacing, ring(-0.35), options, &report);
        return report["head_top"]["columns_topped_facing_down"].get<int>();
    };
    const int now = facing_down(InpaintOptions{}.top_min_up), strict = facing_down(0.0);
    std::cout << "wall seen edge-on: columns topped facing down " << now
              << " (with every top facing down unseen: " << strict << ")\n";
    EXPECT_GT(strict, 60);       // most of the wall's ~150 outline columns
    EXPECT_LT(now, strict / 3);  // the tops tilted down by more than the bound
}

// Without the ellipsoid the crown's height is inpainted: the biharmonic fill continues the rim's
// slope, OpenCV's Telea averages it and flattens the dome (measured: max 7.7 vs 12.4 mm).
TEST(HeadTop, WithoutTheEllipsoidBiharmonicBeatsTelea) {
    const Eigen::Vector3d axes(0.075, 0.085, 0.11);
    const double crown_cos = std::cos(35 * M_PI / 180);
    const auto xyz = sample(axes, kSpacing, [&](const auto& q, const auto& n) {
        return q.z() > -0.06 && n.z() < crown_cos;
    });
    std::vector<Eigen::Vector3d> normals;
    const SurfacePoints s = with_normals(xyz, axes, normals);
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(0.11));
    double worst[2] = {0, 0};
    for (int biharmonic = 0; biharmonic < 2; ++biharmonic) {
        InpaintOptions options;
        options.ellipsoid = false;
        options.biharmonic = biharmonic == 1;
        const auto added = rgbd::holes::fill_head_top(s, normals, axis, kSpacing, {}, options);
        ASSERT_FALSE(added.position.empty());
        for (const auto& p : added.position)
            worst[biharmonic] = std::max(worst[biharmonic], ellipsoid_distance(axes, p));
    }
    std::cout << "head top without ellipsoid: max surface distance Telea " << worst[0] * 1e3
              << " mm, biharmonic " << worst[1] * 1e3 << " mm\n";
    EXPECT_LT(worst[1], 0.7 * worst[0]);
    EXPECT_LT(worst[1], 0.01);
}

// A flat-topped box (10 x 10 cm, 20 cm tall) whose top face is seen only in a 2 cm band round
// its edge: an ellipsoid fits its top region badly (RMS 2.6 spacings, against 0.15 on the
// ellipsoid head and 1.3 on the noisy Max Planck ring capture), so with the limit at 2
// spacings the crown stays open; with top_without_ellipsoid the inpainted heights close it
// flat, within 1 mm of the true face.
TEST(HeadTop, ATopThatIsNoEllipsoidStaysOpenUnlessAsked) {
    std::vector<Eigen::Vector3d> xyz, normals;
    const double half = 0.05, top = 0.1, s = kSpacing;
    const int n = static_cast<int>(std::round(2 * half / s));
    for (int i = 0; i <= n; ++i)
        for (int k = 0; k <= static_cast<int>(std::round(0.2 / s)); ++k) {
            const double t = -half + i * s, z = -0.1 + k * s;
            for (int side = 0; side < 4; ++side) {
                const Eigen::Vector3d nrm = side == 0   ? Eigen::Vector3d(1, 0, 0)
                                            : side == 1 ? Eigen::Vector3d(-1, 0, 0)
                                            : side == 2 ? Eigen::Vector3d(0, 1, 0)
                                                        : Eigen::Vector3d(0, -1, 0);
                const Eigen::Vector3d along(-nrm.y(), nrm.x(), 0);
                xyz.push_back(half * nrm + t * along + Eigen::Vector3d(0, 0, z));
                normals.push_back(nrm);
            }
        }
    for (int i = 1; i < n; ++i)
        for (int j = 1; j < n; ++j) {
            const double x = -half + i * s, y = -half + j * s;
            if (std::max(std::abs(x), std::abs(y)) < half - 0.02) continue;
            xyz.emplace_back(x, y, top);
            normals.emplace_back(0, 0, 1);
        }
    SurfacePoints pts;
    pts.position = xyz;
    const BodyAxis axis = rgbd::holes::estimate_body_axis(pts, ring(0.1));
    rgbd::Report report;
    InpaintOptions options;
    options.max_ellipsoid_rms = 2.0;
    const auto open =
        rgbd::holes::fill_head_top(pts, normals, axis, kSpacing, ring(0.1), options, &report);
    EXPECT_TRUE(open.position.empty()) << report.dump();
    EXPECT_EQ(report["head_top"]["ellipsoid"], false) << report.dump();
    EXPECT_GT(report["head_top"]["ellipsoid_rms_spacings"].get<double>(), 2.0);
    options.top_without_ellipsoid = true;
    const auto closed =
        rgbd::holes::fill_head_top(pts, normals, axis, kSpacing, ring(0.1), options);
    ASSERT_GT(closed.position.size(), 300u);  // the missing 6 x 6 cm: ~900 points
    for (const auto& p : closed.position) {
        EXPECT_NEAR(p.z(), top, 0.001);
        EXPECT_LT(std::max(std::abs(p.x()), std::abs(p.y())), half - 0.02 + 2 * kSpacing);
    }
}

// §12 test: egg-shaped body (12 x 10 cm, 25 cm tall), 0.3 mm noise, open bottom cut at
// z = -0.15 m, a 6 x 4 cm patch removed on its side. The patch is filled (>= 95 % of its true
// samples within 2 spacings of a new point), the new points lie on the surface (RMS < 1 mm,
// measured 0.41; Telea alone 1.17),
// stay in the patch and leave the bottom cut open.
TEST(LargeHoles, FillsAPatchOnTheSideAndLeavesTheBottomCutOpen) {
    const Eigen::Vector3d& axes = kEggAxes;
    const auto xyz = egg_without_patch(0.0003);
    std::vector<Eigen::Vector3d> normals;
    const SurfacePoints s = with_normals(xyz, axes, normals);
    const auto patch =
        sample(axes, kSpacing, [](const auto& q, const auto&) { return in_side_patch(q); });
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(0.3));
    double telea_rms = 0;
    {
        InpaintOptions telea;
        telea.biharmonic = false;
        const auto t = rgbd::holes::fill_large_holes(s, normals, axis, kSpacing, {}, telea);
        for (const auto& p : t.position) telea_rms += std::pow(ellipsoid_distance(axes, p), 2);
        telea_rms = std::sqrt(telea_rms / std::max<double>(1, t.position.size()));
    }
    rgbd::Report report;
    const auto added =
        rgbd::holes::fill_large_holes(s, normals, axis, kSpacing, {}, InpaintOptions{},
                                      std::numeric_limits<double>::infinity(), &report);
    ASSERT_FALSE(added.position.empty());
    double sq = 0;
    std::size_t outside = 0;
    for (std::size_t i = 0; i < added.position.size(); ++i) {
        const Eigen::Vector3d& p = added.position[i];
        EXPECT_EQ(added.mechanism[i], FillMechanism::kLargeHole);
        sq += std::pow(ellipsoid_distance(axes, p), 2);
        // Within two spacings of the patch (the arc test at the true radius).
        outside += !in_side_patch(p, 2 * kSpacing);
        EXPECT_GT(p.z(), -0.15);
        EXPECT_GT(added.normal[i].dot(outward(axes, p)), 0.9);
    }
    const double rms = std::sqrt(sq / double(added.position.size()));
    std::size_t covered = 0;
    for (const auto& t : patch) {
        double best = std::numeric_limits<double>::infinity();
        for (const auto& p : added.position) best = std::min(best, (p - t).norm());
        covered += best < 2 * kSpacing;
    }
    const double coverage = double(covered) / double(patch.size());
    std::cout << "large hole: " << added.position.size() << " points, RMS " << rms * 1e3
              << " mm (Telea only " << telea_rms * 1e3 << " mm), coverage " << coverage
              << ", outside " << outside << "; " << report.dump() << "\n";
    EXPECT_LT(rms, 0.001);
    EXPECT_LT(rms, telea_rms);
    EXPECT_GE(coverage, 0.95);
    EXPECT_LE(outside, added.position.size() / 100);
}

// The egg's patch on a body painted with 24 vertical stripes (dark / light by angle): the
// exemplar-based colour (Criminisi, the default) continues the stripes through the hole, Telea
// blurs them into the mean. Colour error of the added points against the true stripe colour.
TEST(LargeHoles, ExemplarColourContinuesStripesThatTeleaBlurs) {
    const auto light = [](const Eigen::Vector3d& p) {
        const double t = std::atan2(p.y(), p.x()) + M_PI;
        return static_cast<int>(std::floor(t / (2 * M_PI / 24))) % 2 == 0;
    };
    const rgbd::Rgb dark{40, 50, 150}, bright{230, 200, 60};
    const auto xyz = egg_without_patch(0.0003);
    std::vector<Eigen::Vector3d> normals;
    SurfacePoints s = with_normals(xyz, kEggAxes, normals);
    for (std::size_t i = 0; i < xyz.size(); ++i) s.color[i] = light(xyz[i]) ? bright : dark;
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(0.3));
    auto colour_error = [&](rgbd::holes::ColourInpaint method, double& contrast) {
        InpaintOptions o;
        o.colour = method;
        const auto added = rgbd::holes::fill_large_holes(s, normals, axis, kSpacing, {}, o);
        EXPECT_GT(added.position.size(), 200u);
        double err = 0, mean = 0, sq = 0;
        for (std::size_t i = 0; i < added.position.size(); ++i) {
            const auto t = light(added.position[i]) ? bright : dark;
            const auto c = added.color[i];
            err +=
                (std::abs(int(c.r) - t.r) + std::abs(int(c.g) - t.g) + std::abs(int(c.b) - t.b)) /
                3.0;
            mean += c.r;
            sq += double(c.r) * c.r;
        }
        const double n = std::max<double>(1, added.position.size());
        contrast = std::sqrt(std::max(0.0, sq / n - (mean / n) * (mean / n)));
        return err / n;
    };
    double c_exemplar = 0, c_telea = 0;
    const double e_exemplar = colour_error(rgbd::holes::ColourInpaint::kCriminisi, c_exemplar);
    const double e_telea = colour_error(rgbd::holes::ColourInpaint::kTelea, c_telea);
    std::cout << "stripes: colour error exemplar " << e_exemplar << ", Telea " << e_telea
              << "; red contrast exemplar " << c_exemplar << ", Telea " << c_telea
              << " (true ~95)\n";
    EXPECT_LT(e_exemplar, 0.6 * e_telea);
    EXPECT_GT(c_exemplar, 1.3 * c_telea);
}

// The same patch in front of a ring sensor (at 45 degrees, 15 degrees from the patch's centre):
// the sensor looked at it and measured nothing, a real opening: left open unless fill_openings.
TEST(LargeHoles, AHoleASensorSawThroughStaysOpen) {
    const auto xyz = egg_without_patch(0);
    std::vector<Eigen::Vector3d> normals;
    const SurfacePoints s = with_normals(xyz, kEggAxes, normals);
    const auto sensors = ring(0.02);
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, sensors);
    rgbd::Report report;
    const auto kept =
        rgbd::holes::fill_large_holes(s, normals, axis, kSpacing, sensors, InpaintOptions{},
                                      std::numeric_limits<double>::infinity(), &report);
    EXPECT_TRUE(kept.position.empty()) << report.dump();
    EXPECT_EQ(report["large_holes"]["skipped_seen_through"], 1) << report.dump();
    InpaintOptions open;
    open.fill_openings = true;
    EXPECT_GT(
        rgbd::holes::fill_large_holes(s, normals, axis, kSpacing, sensors, open).position.size(),
        300u);
}

// A body above a narrower neck: the egg for z > -0.02 and a 6 cm cylinder for z < -0.07, the
// 5 cm between them unseen (a level ring above sees neither the egg's underside nor the top of
// the neck). The true surface there is a shelf (the egg's underside, z = -0.02) and the neck;
// inpainting the radius bridges the step with a cone up to 25 mm off both. The two sides of
// that hole do not predict each other, so the step test leaves it to the mesher; without the
// test it is filled (and wrong).
TEST(LargeHoles, AHoleBehindAStepIsLeftOpenByTheStepTest) {
    const Eigen::Vector3d axes(0.12, 0.10, 0.25);
    const double neck = 0.06, neck_top = -0.07, shelf = -0.02;
    auto xyz = sample(axes, kSpacing, [&](const auto& q, const auto&) { return q.z() > shelf; });
    std::vector<Eigen::Vector3d> normals;
    SurfacePoints s = with_normals(xyz, axes, normals);
    const int around = static_cast<int>(2 * M_PI * neck / kSpacing);
    for (double z = -0.2; z < neck_top; z += kSpacing)
        for (int k = 0; k < around; ++k) {
            const double a = 2 * M_PI * (k + 0.5 * (std::lround(z / kSpacing) % 2)) / around;
            const Eigen::Vector3d out(std::cos(a), std::sin(a), 0);
            s.position.push_back(neck * out + Eigen::Vector3d(0, 0, z));
            s.color.push_back({90, 120, 140});
            normals.push_back(out);
        }
    // Distance to the true surface near the gap: the neck (up to the shelf) or the shelf.
    const auto off_truth = [&](const Eigen::Vector3d& p) {
        const double r = std::hypot(p.x(), p.y());
        const double to_neck = std::hypot(r - neck, std::max(0.0, p.z() - shelf));
        const double to_shelf = std::hypot(std::max(0.0, neck - r), p.z() - shelf);
        return std::min(to_neck, std::min(to_shelf, ellipsoid_distance(axes, p)));
    };
    const BodyAxis axis = rgbd::holes::estimate_body_axis(s, ring(0.3));
    InpaintOptions unchecked;
    unchecked.max_step_rms = std::numeric_limits<double>::infinity();
    const auto bridged = rgbd::holes::fill_large_holes(s, normals, axis, kSpacing, {}, unchecked);
    std::size_t far_unchecked = 0;
    for (const auto& p : bridged.position) far_unchecked += off_truth(p) > 0.005;
    rgbd::Report report;
    const auto added =
        rgbd::holes::fill_large_holes(s, normals, axis, kSpacing, {}, InpaintOptions{},
                                      std::numeric_limits<double>::infinity(), &report);
    std::size_t far = 0;
    for (const auto& p : added.position) far += off_truth(p) > 0.005;
    std::cout << "step: unchecked " << bridged.position.size() << " points, " << far_unchecked
              << " > 5 mm off; checked " << added.position.size() << ", " << far << "; "
              << report.dump() << "\n";
    EXPECT_GT(far_unchecked, 100u);
    EXPECT_EQ(far, 0u);
    EXPECT_GE(report["large_holes"]["skipped_step"].get<int>(), 1);
}

TEST(LargeHoles, AClosedSurfaceGetsNothing) {
    const Eigen::Vector3d axes(0.12, 0.10, 0.25);
    const auto xyz =
        sample(axes, kSpacing, [](const auto& q, const auto&) { return q.z() > -0.15; });
    std::vector<Eigen::Vector3d> normals;
    const SurfacePoints s = with_normals(xyz, axes, normals);
    const auto added = rgbd::holes::fill_large_holes(
        s, normals, rgbd::holes::estimate_body_axis(s, ring(0.3)), kSpacing, {}, InpaintOptions{});
    EXPECT_LT(added.position.size(), xyz.size() / 200);
}

TEST(LargeHoles, BadInputIsAnError) {
    std::vector<Eigen::Vector3d> normals;
    SurfacePoints empty;
    EXPECT_THROW(rgbd::holes::estimate_body_axis(empty, {}), rgbd::InputError);
    EXPECT_THROW(
        rgbd::holes::fill_large_holes(empty, normals, BodyAxis{}, kSpacing, {}, InpaintOptions{}),
        rgbd::InputError);
    EXPECT_THROW(
        rgbd::holes::fill_head_top(empty, normals, BodyAxis{}, kSpacing, {}, InpaintOptions{}),
        rgbd::InputError);
    const Eigen::Vector3d axes(0.1, 0.1, 0.1);
    auto xyz = sample(axes, 0.005, [](const auto&, const auto&) { return true; });
    SurfacePoints s = with_normals(xyz, axes, normals);
    // NaN coordinates, missing normals, zero spacing.
    SurfacePoints nan = s;
    nan.position[7].x() = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(rgbd::holes::fill_large_holes(nan, normals, BodyAxis{}, kSpacing, {}, {}),
                 rgbd::InputError);
    EXPECT_THROW(rgbd::holes::fill_head_top(nan, normals, BodyAxis{}, kSpacing, {}, {}),
                 rgbd::InputError);
    std::vector<Eigen::Vector3d> few(3, Eigen::Vector3d::UnitZ());
    EXPECT_THROW(rgbd::holes::fill_large_holes(s, few, BodyAxis{}, kSpacing, {}, {}),
                 rgbd::InputError);
    EXPECT_THROW(rgbd::holes::fill_head_top(s, normals, BodyAxis{}, 0.0, {}, {}), rgbd::InputError);
    // Absurd parameters.
    for (auto set : std::vector<void (*)(InpaintOptions&)>{
             [](InpaintOptions& o) { o.pixel = 0; },
             [](InpaintOptions& o) { o.pixel = std::numeric_limits<double>::quiet_NaN(); },
             [](InpaintOptions& o) { o.telea_radius = -1; },
             [](InpaintOptions& o) { o.top_fraction = 0.9; }, [](InpaintOptions& o) { o.step = 0; },
             [](InpaintOptions& o) { o.min_rim_radial = 2; },
             [](InpaintOptions& o) { o.visible_max_angle_deg = 90; },
             [](InpaintOptions& o) { o.max_ellipsoid_rms = 0; },
             [](InpaintOptions& o) { o.top_component = 2; }}) {
        InpaintOptions o;
        set(o);
        EXPECT_THROW(o.check(), rgbd::InputError);
        EXPECT_THROW(rgbd::holes::fill_large_holes(s, normals, BodyAxis{}, kSpacing, {}, o),
                     rgbd::InputError);
    }
}

}  // namespace
}  // namespace rgbd::holes
