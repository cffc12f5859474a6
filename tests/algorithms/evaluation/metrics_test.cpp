// Tests of the reconstruction and pose metrics on icospheres generated here: identity,
// concentric offset, missing cap (recall), far extra triangle (invented surface), cloud
// results, pose errors with and without gauge removal, determinism, timing.
#include "algorithms/evaluation/metrics.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>

#include "tests/validation/synth_test_shapes.hpp"
#include "toolkit/error.hpp"

namespace rgbd::evaluation {
namespace {

constexpr double kPi = std::numbers::pi;
using synth::testing::icosphere;

double face_area(const Mesh& mesh, Mesh::Face_index f) {
    std::vector<Eigen::Vector3d> c;
    for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
        c.push_back(to_eigen(mesh.point(v)));
    return 0.5 * (c[1] - c[0]).cross(c[2] - c[0]).norm();
}

double mesh_area(const Mesh& mesh) {
    double a = 0.0;
    for (auto f : mesh.faces()) a += face_area(mesh, f);
    return a;
}

MetricOptions fast_options() {
    MetricOptions o;
    o.samples = 50000;
    return o;
}

TEST(Metrics, SampleSurfaceIsAreaUniformAndDeterministic) {
    const Mesh sphere = icosphere(1.0, 3);
    const auto a = sample_surface(sphere, 20000, 5);
    const auto b = sample_surface(sphere, 20000, 5);
    ASSERT_EQ(a.size(), 20000u);
    EXPECT_EQ(a, b);
    // Area-uniform on a sphere: each octant holds 1/8 of the samples.
    int octant[8] = {0};
    for (const auto& p : a) {
        EXPECT_NEAR(p.norm(), 1.0, 0.01);
        octant[(p.x() > 0) + 2 * (p.y() > 0) + 4 * (p.z() > 0)]++;
    }
    for (int o : octant) EXPECT_NEAR(o / 20000.0, 0.125, 0.01);
    EXPECT_THROW(sample_surface(Mesh{}, 10, 1), InputError);
}

TEST(Metrics, IdenticalMeshes) {
    const Mesh sphere = icosphere(1.0, 3);
    const SurfaceMetrics m = compare_to_reference(&sphere, nullptr, sphere, fast_options());
    EXPECT_LT(m.chamfer_m, 1e-9);
    EXPECT_LT(m.hausdorff_m, 1e-9);
    for (const auto& t : m.thresholds) EXPECT_EQ(t.fscore, 1.0);
    EXPECT_EQ(m.invented_surface_fraction, 0.0);
    ASSERT_TRUE(m.normal_consistency.has_value());
    EXPECT_NEAR(*m.normal_consistency, 1.0, 1e-9);
    const Report j = m.to_json();
    for (const char* key :
         {"chamfer_m", "hausdorff_m", "hausdorff_p95_m", "fscore_2mm", "precision_2mm",
          "recall_2mm", "fscore_5mm", "precision_5mm", "recall_5mm", "invented_surface_fraction",
          "completeness_mean_m", "accuracy_mean_m", "normal_consistency"})
        EXPECT_TRUE(j.contains(key)) << key;
}

TEST(Metrics, ConcentricSpheresOnePercentApart) {
    const Mesh reference = icosphere(1.0, 4);
    const Mesh result = icosphere(1.01, 4);
    MetricOptions options = fast_options();
    options.taus_m = {0.005, 0.02};
    const SurfaceMetrics m = compare_to_reference(&result, nullptr, reference, options);
    EXPECT_NEAR(m.chamfer_m, 0.01, 0.0002);
    EXPECT_NEAR(m.hausdorff_m, 0.01, 0.0007);
    EXPECT_EQ(m.thresholds[0].fscore, 0.0);
    EXPECT_EQ(m.thresholds[1].fscore, 1.0);
    EXPECT_EQ(m.invented_surface_fraction, 1.0);  // every point is 10 mm off (> 5 mm)
    const Report j = m.to_json();
    EXPECT_EQ(j["fscore_5mm"].get<double>(), 0.0);
    EXPECT_EQ(j["fscore_20mm"].get<double>(), 1.0);
}

TEST(Metrics, MissingCapLowersRecallByItsAreaShare) {
    const Mesh reference = icosphere(1.0, 4);
    Mesh result = icosphere(1.0, 4);
    double cap = 0.0;
    for (auto f : result.faces()) {
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (auto v : CGAL::vertices_around_face(result.halfedge(f), result))
            c += to_eigen(result.point(v)) / 3.0;
        if (c.z() > 0.8) {
            cap += face_area(result, f);
            result.remove_face(f);
        }
    }
    result.collect_garbage();
    const double share = cap / mesh_area(reference);
    EXPECT_NEAR(share, 0.1, 0.01);
    const SurfaceMetrics m = compare_to_reference(&result, nullptr, reference, fast_options());
    for (const auto& t : m.thresholds) {
        EXPECT_NEAR(t.recall, 1.0 - share, 0.01) << t.tau_m;
        EXPECT_EQ(t.precision, 1.0);
    }
    EXPECT_EQ(m.invented_surface_fraction, 0.0);
    EXPECT_GT(m.hausdorff_m, 0.3);  // the cap's pole is far from the rim
}

TEST(Metrics, FarTriangleIsInventedSurface) {
    const Mesh reference = icosphere(1.0, 4);
    Mesh result = icosphere(1.0, 4);
    const auto a = result.add_vertex(Point_3(3, 0, 0));
    const auto b = result.add_vertex(Point_3(4.5, 0, 0));
    const auto c = result.add_vertex(Point_3(3, 1.5, 0));
    result.add_face(a, b, c);
    const double share = 1.125 / mesh_area(result);
    MetricOptions options = fast_options();
    options.samples = 200000;
    const SurfaceMetrics m = compare_to_reference(&result, nullptr, reference, options);
    EXPECT_NEAR(m.invented_surface_fraction, share, 0.004);
    EXPECT_NEAR(m.thresholds[0].precision, 1.0 - share, 0.004);
    EXPECT_EQ(m.thresholds[0].recall, 1.0);
}

TEST(Metrics, CloudResult) {
    const Mesh reference = icosphere(0.1, 4);
    PointCloud cloud;
    for (const auto& p : sample_surface(reference, 100000, 9)) cloud.points.insert(to_point(p));
    const SurfaceMetrics m = compare_to_reference(nullptr, &cloud, reference, fast_options());
    EXPECT_LT(m.accuracy.max, 1e-9);
    EXPECT_FALSE(m.normal_consistency.has_value());
    // 100k points on 0.126 m^2: spacing ~ 1.1 mm, nearest point within 5 mm always.
    EXPECT_GT(m.thresholds[1].recall, 0.999);
    EXPECT_EQ(m.result_samples, 100000u);
    PointCloud empty;
    EXPECT_THROW(compare_to_reference(nullptr, &empty, reference, fast_options()), InputError);
    EXPECT_THROW(compare_to_reference(nullptr, nullptr, reference, fast_options()), InputError);
    EXPECT_THROW(compare_to_reference(&reference, nullptr, Mesh{}, fast_options()), InputError);
}

TEST(Metrics, SameResultForOneAndManyThreads) {
    const Mesh reference = icosphere(1.0, 3);
    const Mesh result = icosphere(1.003, 2);
    Report one;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        one = compare_to_reference(&result, nullptr, reference, fast_options()).to_json();
    }
    Report many = compare_to_reference(&result, nullptr, reference, fast_options()).to_json();
    one.erase("time_s");
    many.erase("time_s");
    EXPECT_EQ(one, many);
}

/// within_distance answers as distances_to_points(...) <= tau for every query: near the cloud,
/// at about tau (both sides of it), far from it, and outside the cloud's bounding box.
TEST(Metrics, WithinDistanceAgreesWithTheNearestDistance) {
    std::vector<Eigen::Vector3d> cloud, queries;
    std::uint64_t s = 7;
    const auto uniform = [&s] {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        return double(s >> 11) / double(1ull << 53);
    };
    for (int i = 0; i < 20000; ++i) {  // a noisy unit sphere
        const Eigen::Vector3d d(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5);
        if (d.norm() > 1e-3) cloud.push_back(d.normalized() * (1.0 + 0.002 * uniform()));
    }
    for (int i = 0; i < 5000; ++i) {  // from the centre to twice the radius
        const Eigen::Vector3d d(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5);
        if (d.norm() > 1e-3) queries.push_back(d.normalized() * (2.0 * uniform()));
    }
    queries.push_back(cloud[5]);                                // on a point
    queries.push_back(cloud[9] + Eigen::Vector3d(0.01, 0, 0));  // exactly tau off, or less
    queries.push_back(Eigen::Vector3d(-50.0, 3.0, 1e3));        // far outside the grid
    const std::vector<double> d = distances_to_points(queries, cloud);
    for (double tau : {0.002, 0.01, 0.05}) {
        const std::vector<char> near = within_distance(queries, cloud, tau);
        ASSERT_EQ(near.size(), queries.size());
        std::size_t yes = 0;
        for (std::size_t i = 0; i < queries.size(); ++i) {
            EXPECT_EQ(near[i] != 0, d[i] <= tau) << "query " << i << " at " << d[i] << " m";
            yes += near[i] != 0;
        }
        EXPECT_GT(yes, 0u);  // both answers occur
        EXPECT_LT(yes, queries.size());
    }
    EXPECT_THROW(within_distance(queries, {}, 0.01), InputError);
    EXPECT_THROW(within_distance(queries, cloud, 0.0), InputError);
    EXPECT_THROW(within_distance(queries, cloud, std::nan("")), InputError);
}

std::map<std::string, Pose> ring(int n) {
    std::map<std::string, Pose> poses;
    for (int i = 0; i < n; ++i) {
        const double a = 2 * kPi * i / n;
        Pose p = Eigen::Translation3d(1.5 * std::cos(a), 0.1 * i, 1.5 * std::sin(a)) *
                 Eigen::AngleAxisd(-a - kPi / 2, Eigen::Vector3d::UnitY());
        poses["k2-" + std::to_string(i)] = p;
    }
    return poses;
}

TEST(PoseErrors, KnownPerturbationIsRecovered) {
    const auto truth = ring(8);
    auto estimated = truth;
    estimated["k2-3"] = estimated["k2-3"] *
                        Eigen::AngleAxisd(2.0 * kPi / 180, Eigen::Vector3d(1, 2, 3).normalized());
    estimated["k2-3"].translation() += Eigen::Vector3d(0.003, 0.0, -0.004);
    estimated.erase("k2-7");
    const PoseErrors e = pose_errors(estimated, truth, /*remove_gauge=*/false);
    ASSERT_EQ(e.per_sensor.size(), 7u);
    EXPECT_EQ(e.missing, std::vector<std::string>{"k2-7"});
    for (const auto& s : e.per_sensor) {
        if (s.sensor == "k2-3") {
            EXPECT_NEAR(s.rotation_deg, 2.0, 1e-9);
            EXPECT_NEAR(s.translation_mm, 5.0, 1e-9);
        } else {
            EXPECT_NEAR(s.rotation_deg, 0.0, 1e-6);
            EXPECT_NEAR(s.translation_mm, 0.0, 1e-9);
        }
    }
    EXPECT_NEAR(e.max_rotation_deg, 2.0, 1e-9);
    EXPECT_NEAR(e.mean_translation_mm, 5.0 / 7.0, 1e-9);
    EXPECT_EQ(e.to_json()["per_sensor"]["k2-3"]["translation_mm"].get<double>(),
              e.per_sensor[3].translation_mm);
}

TEST(PoseErrors, GaugeRemovalCancelsAGlobalTransform) {
    const auto truth = ring(8);
    const Pose g = Eigen::Translation3d(0.4, -1.0, 2.0) *
                   Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 1.0, -0.3).normalized());
    std::map<std::string, Pose> estimated;
    for (const auto& [k, p] : truth) estimated[k] = g * p;
    const PoseErrors raw = pose_errors(estimated, truth, false);
    EXPECT_GT(raw.mean_rotation_deg, 10.0);
    const PoseErrors e = pose_errors(estimated, truth, true);
    EXPECT_EQ(e.gauge_method, "umeyama");
    EXPECT_LT(e.max_rotation_deg, 1e-6);
    EXPECT_LT(e.max_translation_mm, 1e-6);
    // Two sensors: fallback to the first pose.
    std::map<std::string, Pose> two{{"a", estimated.at("k2-0")}, {"b", estimated.at("k2-1")}};
    std::map<std::string, Pose> two_truth{{"a", truth.at("k2-0")}, {"b", truth.at("k2-1")}};
    const PoseErrors f = pose_errors(two, two_truth, true);
    EXPECT_EQ(f.gauge_method, "first_pose");
    EXPECT_LT(f.max_rotation_deg, 1e-6);
    EXPECT_LT(f.max_translation_mm, 1e-6);
    EXPECT_THROW(pose_errors({}, truth, true), InputError);
}

TEST(Performance, Metrics200kSamples20kTriangles) {
    const Mesh reference = icosphere(1.0, 5);  // 20480 triangles
    const Mesh result = icosphere(1.002, 5);
    MetricOptions options;  // 200k samples
    const SurfaceMetrics m = compare_to_reference(&result, nullptr, reference, options);
    std::printf("metrics, 200k samples per side, 20480 triangles: %.3f s\n", m.time_s);
    RecordProperty("time_s", std::to_string(m.time_s));
    EXPECT_NEAR(m.chamfer_m, 0.002, 0.0002);
}

}  // namespace
}  // namespace rgbd::evaluation
