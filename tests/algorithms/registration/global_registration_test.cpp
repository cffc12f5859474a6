#include "algorithms/registration/global_registration.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <random>

#include "algorithms/registration/pose_graph.hpp"
#include "synthetic_views.hpp"
#include "toolkit/error.hpp"

namespace {

using rgbd::Pose;
using rgbd::registration::Fpfh;

/// Points and outward normals of one view of the bumpy ellipsoid (normals from the implicit
/// surface by central differences), in the sensor frame.
struct Cloud {
    std::vector<Eigen::Vector3d> xyz, normals;
};

Cloud view_of(const Pose& world_from_sensor, std::uint32_t seed) {
    const rgbd::test::BumpyEllipsoid shape;
    const rgbd::PointCloud v =
        rgbd::test::render_view(shape, world_from_sensor, 0, 0.0003, seed, 4);
    Cloud c;
    const Pose sensor_from_world = world_from_sensor.inverse();
    for (auto idx : v.points) {
        const Eigen::Vector3d p = rgbd::to_eigen(v.points.point(idx));
        const Eigen::Vector3d w = world_from_sensor * p;
        Eigen::Vector3d g;
        const double h = 1e-4;
        for (int k = 0; k < 3; ++k) {
            Eigen::Vector3d e = Eigen::Vector3d::Zero();
            e[k] = h;
            g[k] = shape.value(w + e) - shape.value(w - e);
        }
        c.xyz.push_back(p);
        c.normals.push_back((sensor_from_world.linear() * g).normalized());
    }
    return c;
}

TEST(GlobalRegistration, FpfhIsInvariantToRigidMotion) {
    const Cloud c = view_of(rgbd::test::look_at({0, 0.1, -0.8}, {0, 0, 0}), 1);
    std::mt19937 rng(3);
    const Pose m = rgbd::test::random_motion(70.0, 0.4, rng);
    std::vector<Eigen::Vector3d> moved_xyz, moved_n;
    for (std::size_t i = 0; i < c.xyz.size(); ++i) {
        moved_xyz.push_back(m * c.xyz[i]);
        moved_n.push_back(m.linear() * c.normals[i]);
    }
    const auto a = rgbd::registration::compute_fpfh(c.xyz, c.normals, 0.03);
    const auto b = rgbd::registration::compute_fpfh(moved_xyz, moved_n, 0.03);
    ASSERT_EQ(a.size(), c.xyz.size());
    double worst = 0, norm = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        worst = std::max(worst, double((a[i] - b[i]).norm()));
        norm = std::max(norm, double(a[i].norm()));
    }
    EXPECT_GT(norm, 10.0);  // descriptors are not empty
    EXPECT_LT(worst, 1e-2 * norm);
}

TEST(GlobalRegistration, RansacRecoversALargeMotionBetweenOverlappingViews) {
    // Two sensors 40 degrees apart; the source is handed over in a frame off by 60 degrees and
    // 0.3 m: far beyond any ICP basin.
    const Pose ta = rgbd::test::look_at({0, 0.1, -0.8}, {0, 0, 0});
    const Pose tb =
        rgbd::test::look_at({0.8 * std::sin(0.7), 0.1, -0.8 * std::cos(0.7)}, {0, 0, 0});
    const Cloud a = view_of(ta, 1), b = view_of(tb, 2);
    const Pose truth = ta.inverse() * tb;  // a_from_b
    const auto fa = rgbd::registration::compute_fpfh(a.xyz, a.normals, 0.03);
    const auto fb = rgbd::registration::compute_fpfh(b.xyz, b.normals, 0.03);
    rgbd::registration::RansacOptions o;
    o.inlier_distance = 0.008;
    o.seed = 5;
    rgbd::registration::RansacResult r1, r2;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        r1 = rgbd::registration::ransac_feature_match(b.xyz, fb, a.xyz, fa, o);
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
        r2 = rgbd::registration::ransac_feature_match(b.xyz, fb, a.xyz, fa, o);
    }
    ASSERT_TRUE(r1.found);
    EXPECT_TRUE(r1.target_from_source.matrix() == r2.target_from_source.matrix());
    EXPECT_LT(rgbd::rotation_error_deg(r1.target_from_source, truth), 3.0);
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : b.xyz) c += p;
    c /= double(b.xyz.size());
    EXPECT_LT((r1.target_from_source * c - truth * c).norm(), 0.01);
    // A prior that excludes the truth leaves only wrong hypotheses, or none.
    o.prior = Pose(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).matrix() * truth.linear());
    o.prior->translation() = truth.translation();
    o.max_prior_rotation_deg = 10.0;
    const auto r3 = rgbd::registration::ransac_feature_match(b.xyz, fb, a.xyz, fa, o);
    if (r3.found) {
        EXPECT_GT(rgbd::rotation_error_deg(r3.target_from_source, truth), 100.0);
    }
}

TEST(GlobalRegistration, BadInput) {
    std::vector<Eigen::Vector3d> p(3, Eigen::Vector3d::Zero()), n(2, Eigen::Vector3d::UnitZ());
    EXPECT_THROW(rgbd::registration::compute_fpfh(p, n, 0.01), rgbd::InputError);
    n.resize(3);
    EXPECT_THROW(rgbd::registration::compute_fpfh(p, n, -1.0), rgbd::InputError);
    EXPECT_THROW(rgbd::registration::compute_fpfh(p, n, std::nan("")), rgbd::InputError);
    rgbd::registration::RansacOptions o;
    o.inlier_distance = 0;
    EXPECT_THROW(rgbd::registration::ransac_feature_match(p, {}, p, {}, o), rgbd::InputError);
}

/// Ring of n poses on a circle; edges i -> i+1 measured with small noise.
struct Graph {
    std::vector<Pose> truth;
    std::vector<rgbd::registration::PoseGraphEdge> edges;
};

Graph ring_graph(int n, std::uint32_t seed) {
    std::mt19937 rng(seed);
    Graph g;
    for (int i = 0; i < n; ++i) {
        const double yaw = 2 * M_PI * i / n;
        g.truth.push_back(
            rgbd::test::look_at({1.5 * std::sin(yaw), 0.3, -1.5 * std::cos(yaw)}, {0, 0, 0}));
    }
    for (int i = 0; i < n; ++i) {
        rgbd::registration::PoseGraphEdge e;
        e.target = i;
        e.source = (i + 1) % n;
        e.target_from_source = g.truth[e.target].inverse() * g.truth[e.source] *
                               rgbd::test::random_motion(0.1, 0.001, rng);
        e.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e4;
        g.edges.push_back(e);
    }
    return g;
}

TEST(PoseGraph, SpreadsTheLoopErrorOverTheRing) {
    const Graph g = ring_graph(8, 1);
    // Start: the edges chained from node 0 (the whole loop error lands on the last edge).
    std::vector<Pose> start(8);
    start[0] = g.truth[0];
    for (int i = 1; i < 8; ++i) start[i] = start[i - 1] * g.edges[i - 1].target_from_source;
    const double chained_last = rgbd::registration::edge_residual(start, g.edges[7]).rotation_deg;
    rgbd::registration::PoseGraphOptions o;
    o.prune_rotation_deg = 5.0;
    o.prune_translation_m = 0.05;
    const auto r = rgbd::registration::optimise_pose_graph(start, g.edges, o);
    double worst_edge = 0, worst_pose = 0;
    for (const auto& e : r.residuals) worst_edge = std::max(worst_edge, e.rotation_deg);
    for (int i = 0; i < 8; ++i)
        worst_pose = std::max(worst_pose, rgbd::rotation_error_deg(r.poses[i], g.truth[i]));
    EXPECT_LT(r.final_cost, r.initial_cost);
    EXPECT_LT(worst_edge, chained_last);  // spread, not left on one edge
    EXPECT_LT(worst_pose, 0.3);
    EXPECT_TRUE(r.poses[0].isApprox(start[0]));  // the gauge holds
    for (bool a : r.active) EXPECT_TRUE(a);
}

TEST(PoseGraph, PrunesAnEdgeThatDisagreesWithTheRing) {
    Graph g = ring_graph(8, 2);
    // Chords i -> i+2 make the bad edge identifiable; edge 3 is off by 20 degrees.
    for (int i = 0; i < 8; ++i) {
        rgbd::registration::PoseGraphEdge e;
        e.target = i;
        e.source = (i + 2) % 8;
        e.target_from_source = g.truth[e.target].inverse() * g.truth[e.source];
        e.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e4;
        g.edges.push_back(e);
    }
    g.edges[3].target_from_source =
        g.edges[3].target_from_source *
        Pose(Eigen::AngleAxisd(20 * M_PI / 180, Eigen::Vector3d::UnitY()).matrix());
    std::vector<Pose> start = g.truth;
    std::mt19937 rng(4);
    for (int i = 1; i < 8; ++i) start[i] = start[i] * rgbd::test::random_motion(3.0, 0.03, rng);
    const auto r = rgbd::registration::optimise_pose_graph(start, g.edges, {});
    EXPECT_FALSE(r.active[3]);
    int inactive = 0;
    for (bool a : r.active) inactive += a ? 0 : 1;
    EXPECT_EQ(inactive, 1);
    for (int i = 0; i < 8; ++i) EXPECT_LT(rgbd::rotation_error_deg(r.poses[i], g.truth[i]), 0.3);
}

TEST(PoseGraph, BadInput) {
    Graph g = ring_graph(4, 3);
    rgbd::registration::PoseGraphOptions o;
    o.fixed_node = 9;
    EXPECT_THROW(rgbd::registration::optimise_pose_graph(g.truth, g.edges, o), rgbd::InputError);
    g.edges[0].source = 7;
    EXPECT_THROW(rgbd::registration::optimise_pose_graph(g.truth, g.edges, {}), rgbd::InputError);
    g = ring_graph(4, 3);
    g.truth[1].matrix()(0, 0) = std::nan("");
    EXPECT_THROW(rgbd::registration::optimise_pose_graph(g.truth, g.edges, {}), rgbd::InputError);
}

}  // namespace
