// Live fusion (pipeline/video_fusion.hpp): the voxel edge from the rig's resolution, a frame
// made into a cleaned world-frame view at its rig pose, and two overlapping views fused into
// one cloud of one-view density on the surface.
#include "pipeline/video_fusion.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace {

using rgbd::Pose;

rgbd::io::SensorSpec kinect(const Pose& world_from_depth) {
    rgbd::io::SensorSpec s;
    s.id = "k";
    s.depth = {512, 424, 365.5, 365.5, 256, 212};
    s.color = {512, 424, 365.5, 365.5, 256, 212};
    s.world_from_depth = world_from_depth;
    s.noise_model = "kinect_v2";
    return s;
}

/// Depth camera at the origin looking along +z at a fronto-parallel wall at z = 1.5 m, 0.6 m
/// wide, grey-green; elsewhere nothing.
rgbd::RgbdFrame wall_frame(const Pose& world_from_depth, cv::Vec3b bgr = {90, 160, 120}) {
    const auto spec = kinect(world_from_depth);
    cv::Mat depth(424, 512, CV_16UC1, cv::Scalar(0));
    cv::Mat color(424, 512, CV_8UC3, cv::Scalar(0, 0, 0));
    for (int v = 0; v < 424; ++v)
        for (int u = 0; u < 512; ++u) {
            const double x = (u - 256) / 365.5 * 1.5, y = (v - 212) / 365.5 * 1.5;
            if (std::abs(x) < 0.3 && std::abs(y) < 0.3) {
                depth.at<std::uint16_t>(v, u) = 1500;
                color.at<cv::Vec3b>(v, u) = bgr;
            }
        }
    return rgbd::io::frame_from_stored(spec, depth, color, "wall");
}

TEST(VideoFusion, VoxelIsThePixelFootprintAtTheObject) {
    rgbd::io::Rig rig;
    // Two sensors 1.5 m from the origin, looking at it.
    for (double a : {0.0, M_PI}) {
        Pose p = Pose::Identity();
        const Eigen::Vector3d eye(1.5 * std::cos(a), 1.5 * std::sin(a), 0);
        const Eigen::Vector3d z = -eye.normalized(), x = Eigen::Vector3d::UnitZ().cross(z);
        p.linear().col(0) = x;
        p.linear().col(1) = z.cross(x);
        p.linear().col(2) = z;
        p.translation() = eye;
        rig.sensors.push_back(kinect(p));
    }
    EXPECT_NEAR(rgbd::pipeline::video_voxel_m(rig, Eigen::Vector3d::Zero()), 1.5 / 365.5, 1e-9);
    EXPECT_NEAR(rgbd::pipeline::video_voxel_m(rig, std::nullopt), 1.5 / 365.5, 1e-9);
}

TEST(VideoFusion, ViewsAtTheirPosesFuseIntoOneLayerOnTheSurface) {
    Pose a = Pose::Identity(), b = Pose::Identity();
    a.translation() = Eigen::Vector3d(0, 0, -1.5);  // the wall at world z = 0
    b = a;
    b.translation().x() = 0.1;  // a second sensor 10 cm to the side: the views overlap
    rgbd::pipeline::VideoFusionOptions options;
    const Eigen::Vector3d centre(0, 0, 0);
    rgbd::Report report;
    rgbd::PointCloud va = rgbd::pipeline::fusion_view(wall_frame(a), 0, options, centre, &report);
    EXPECT_GT(va.size(), 20000u);
    EXPECT_EQ(va.view.frame, rgbd::ViewFrame::kWorld);
    ASSERT_TRUE(va.has_colors());
    for (auto i : va.points) {
        ASSERT_NEAR(va.points.point(i).z(), 0.0, 1e-3);
        ASSERT_LE(std::abs(va.points.point(i).x()), 0.302);
    }
    rgbd::PointCloud vb = rgbd::pipeline::fusion_view(wall_frame(b), 1, options, centre);
    const std::size_t one = va.size();
    const double voxel = 0.004;
    std::vector<rgbd::PointCloud> views;
    views.push_back(std::move(va));
    views.push_back(std::move(vb));
    views.emplace_back();  // a missing view (a thinned set) is allowed
    rgbd::Report fuse_report;
    const rgbd::PointCloud fused =
        rgbd::pipeline::fuse_views(std::move(views), voxel, options, &fuse_report);
    EXPECT_EQ(fuse_report["views"], 2);
    EXPECT_GT(fuse_report["duplicates"].get<std::size_t>(), one / 2);
    // One point per 4 mm voxel over the union (0.7 x 0.6 m): about 26k, far below two views.
    EXPECT_NEAR(static_cast<double>(fused.size()), 0.7 * 0.6 / (voxel * voxel), 0.15 * 26250);
    ASSERT_TRUE(fused.has_colors());
    const auto cm = fused.colors();
    for (auto i : fused.points) {
        ASSERT_NEAR(fused.points.point(i).z(), 0.0, 1e-3);
        ASSERT_NEAR(cm.get(i).g, 160, 1);  // colour kept (BGR 90,160,120 -> RGB 120,160,90)
    }

    // The hub's one-pass fusion gives the same cloud as the general-purpose functions.
    const auto pa =
        rgbd::io::to_colored_points(rgbd::pipeline::fusion_view(wall_frame(a), 0, options, centre));
    const auto pb =
        rgbd::io::to_colored_points(rgbd::pipeline::fusion_view(wall_frame(b), 1, options, centre));
    rgbd::Report fast_report;
    const rgbd::io::ColoredPoints fast =
        rgbd::pipeline::fuse_points({{&pa, a.translation()}, {&pb, b.translation()}, {nullptr, {}}},
                                    voxel, options, &fast_report);
    EXPECT_EQ(fast_report["views"], 2);
    EXPECT_NEAR(static_cast<double>(fast.size()), static_cast<double>(fused.size()),
                0.03 * static_cast<double>(fused.size()));
    for (std::size_t i = 0; i < fast.size(); ++i) {
        ASSERT_NEAR(fast.xyz[i].z(), 0.0, 1e-3);
        ASSERT_EQ(fast.rgb[i], (rgbd::Rgb{120, 160, 90}));
    }
}

TEST(VideoFusion, WhereColoursDisagreeTheBetterObservedViewWins) {
    // Two sensors see the same wall in different colours (a specular highlight, a bad white
    // balance): per voxel, the nearer sensor's colour is kept, never a mix.
    Pose near = Pose::Identity(), far = Pose::Identity();
    near.translation() = Eigen::Vector3d(0, 0, -1.5);
    far.translation() = Eigen::Vector3d(0, 0, -1.5);
    rgbd::pipeline::VideoFusionOptions options;
    options.extraction.crop_radius_m = 0;
    const auto green = rgbd::io::to_colored_points(
        rgbd::pipeline::fusion_view(wall_frame(near, {90, 160, 120}), 0, options, std::nullopt));
    const auto red = rgbd::io::to_colored_points(
        rgbd::pipeline::fusion_view(wall_frame(far, {40, 40, 220}), 1, options, std::nullopt));
    for (const Eigen::Vector3d& red_sensor :
         {Eigen::Vector3d(0, 0, -3.0), Eigen::Vector3d(0, 0, -1.0)}) {
        rgbd::Report report;
        const auto fused = rgbd::pipeline::fuse_points(
            {{&green, near.translation()}, {&red, red_sensor}}, 0.004, options, &report);
        EXPECT_GT(report["replaced"].get<std::size_t>(), fused.size() * 9 / 10);
        const rgbd::Rgb expected =
            red_sensor.z() < -2 ? rgbd::Rgb{120, 160, 90} : rgbd::Rgb{220, 40, 40};
        std::size_t kept = 0;
        for (const rgbd::Rgb c : fused.rgb) kept += c == expected;
        EXPECT_GT(kept, fused.size() * 99 / 100);
    }
}

}  // namespace
