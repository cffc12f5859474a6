#include "algorithms/registration/icp.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/sampling/voxel_downsample.hpp"
#include "synthetic_views.hpp"
#include "toolkit/error.hpp"

namespace {

using rgbd::PointCloud;
using rgbd::Pose;

struct PairScene {
    PointCloud source, target;  // world frame; source moved by `motion`
    Pose truth;                 // target_from_source that undoes the motion
};

PairScene make_pair_scene() {
    const rgbd::test::BumpyEllipsoid shape;
    const double yaw = 35.0 * M_PI / 180.0;
    const Pose cam_a = rgbd::test::look_at({0.0, 0.1, -0.8}, shape.centre);
    const Pose cam_b =
        rgbd::test::look_at({0.8 * std::sin(yaw), 0.1, -0.8 * std::cos(yaw)}, shape.centre);
    PairScene scene;
    scene.source = rgbd::test::render_view(shape, cam_a, 0, 0.0005, 1);
    scene.target = rgbd::test::render_view(shape, cam_b, 1, 0.0005, 2);
    rgbd::to_world_frame(scene.source);
    rgbd::to_world_frame(scene.target);
    rgbd::normals::estimate_normals(scene.source, {});
    rgbd::normals::estimate_normals(scene.target, {});
    // 3 degrees about an oblique axis through the object centre, 20 mm.
    Pose motion = Pose::Identity();
    motion.linear() =
        Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d(0.3, 1.0, -0.4).normalized())
            .toRotationMatrix();
    motion.translation() = Eigen::Vector3d(0.012, -0.010, 0.0122);  // |t| = 20 mm
    rgbd::transform(scene.source, motion);
    scene.truth = motion.inverse();
    return scene;
}

const PairScene& scene() {
    static const PairScene s = make_pair_scene();
    return s;
}

TEST(AlignPair, RecoversKnownOffset) {
    const PairScene& s = scene();
    rgbd::registration::IcpOptions options;
    const auto result =
        rgbd::registration::align_pair(s.source, s.target, Pose::Identity(), options);
    // Errors at the object (its centre is the world origin).
    EXPECT_LT(rgbd::rotation_error_deg(result.target_from_source, s.truth), 0.1);
    EXPECT_LT(rgbd::translation_error_m(result.target_from_source, s.truth), 0.001);
    EXPECT_GT(result.fitness, 0.5);
    EXPECT_LT(result.inlier_rmse, 0.003);
    EXPECT_GT(result.iterations, 0);
    EXPECT_TRUE(result.to_json().contains("inlier_rmse_m"));
}

TEST(AlignPair, RecoversWithHuberAndDownsampledSource) {
    const PairScene& s = scene();
    rgbd::registration::IcpOptions options;
    options.kernel = rgbd::registration::RobustKernel::kHuber;
    const PointCloud small = rgbd::sampling::voxel_downsample(s.source, 0.004);
    const auto result = rgbd::registration::align_pair(small, s.target, Pose::Identity(), options);
    EXPECT_LT(rgbd::rotation_error_deg(result.target_from_source, s.truth), 0.1);
    EXPECT_LT(rgbd::translation_error_m(result.target_from_source, s.truth), 0.001);
}

TEST(AlignPair, BitIdenticalForOneAndTwoThreads) {
    const PairScene& s = scene();
    rgbd::registration::IcpOptions options;
    rgbd::registration::AlignResult one, two;
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
        one = rgbd::registration::align_pair(s.source, s.target, Pose::Identity(), options);
    }
    {
        tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
        two = rgbd::registration::align_pair(s.source, s.target, Pose::Identity(), options);
    }
    EXPECT_TRUE(one.target_from_source.matrix() == two.target_from_source.matrix());
    EXPECT_EQ(one.fitness, two.fitness);
    EXPECT_EQ(one.inlier_rmse, two.inlier_rmse);
    EXPECT_EQ(one.iterations, two.iterations);
}

TEST(AlignPair, BadInput) {
    const PairScene& s = scene();
    rgbd::registration::IcpOptions options;
    PointCloud no_normals;
    no_normals.view.id = 3;
    no_normals.points.insert(rgbd::Point_3(0, 0, 0));
    EXPECT_THROW(rgbd::registration::align_pair(s.source, no_normals, Pose::Identity(), options),
                 rgbd::InputError);
    EXPECT_THROW(rgbd::registration::align_pair(PointCloud{}, s.target, Pose::Identity(), options),
                 rgbd::InputError);
    rgbd::registration::IcpOptions bad;
    bad.max_distances_m = {0.01, -1.0};
    EXPECT_THROW(bad.check(), rgbd::InputError);
    bad = {};
    bad.criteria.max_iterations = 0;
    EXPECT_THROW(bad.check(), rgbd::InputError);
}

}  // namespace
