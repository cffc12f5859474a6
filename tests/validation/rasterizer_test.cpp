// Exactness of the synthetic renderer: analytic plane and sphere depths, colour-camera
// occlusion, determinism for any number of threads.
#include "validation/synth/rasterizer.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>

#include "synth_test_shapes.hpp"
#include "toolkit/error.hpp"
#include "validation/synth/synthesize.hpp"

namespace rgbd::synth {
namespace {

bool same_bits(const cv::Mat& a, const cv::Mat& b) {
    return a.size() == b.size() && a.type() == b.type() && a.isContinuous() && b.isContinuous() &&
           std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

TEST(Rasterizer, PlaneDepthIsAnalyticAtEveryPixel) {
    const io::SensorSpec spec = kinect_v2_spec("k");
    const Pose world_from_camera =
        look_at(Eigen::Vector3d(0.3, -1.2, 1.6), Eigen::Vector3d(0, 0, 1.3));
    const Eigen::Vector3d p0(0.05, 0.1, 1.35);
    const Eigen::Vector3d n = Eigen::Vector3d(0.2, -1.0, 0.5).normalized();
    const Eigen::Vector3d a = n.cross(Eigen::Vector3d::UnitZ()).normalized();
    const Eigen::Vector3d b = n.cross(a);
    Mesh mesh;
    testing::add_quad(mesh, p0, a, b, 0.4);
    const DepthRender r = render_depth(RenderScene(mesh), spec.depth, world_from_camera);

    const Pose camera_from_world = world_from_camera.inverse();
    const Eigen::Vector3d nc = camera_from_world.linear() * n;
    const double dc = nc.dot(camera_from_world * p0);
    const auto& k = spec.depth;
    long covered = 0, missed = 0;
    double worst = 0;
    for (int row = 0; row < k.height; ++row)
        for (int col = 0; col < k.width; ++col) {
            const Eigen::Vector3d ray((col - k.cx) / k.fx, (row - k.cy) / k.fy, 1.0);
            const double z = dc / nc.dot(ray);
            const Eigen::Vector3d p = world_from_camera * (z * ray) - p0;
            const bool inside = std::abs(p.dot(a)) < 0.4 - 1e-3 && std::abs(p.dot(b)) < 0.4 - 1e-3;
            const double d = r.depth.at<double>(row, col);
            if (std::isfinite(d)) {
                ++covered;
                worst = std::max(worst, std::abs(d - z));
                EXPECT_GE(r.triangle.at<int>(row, col), 0);
                const cv::Vec3f nn = r.normal.at<cv::Vec3f>(row, col);
                EXPECT_NEAR(std::abs(nn[0] * nc.x() + nn[1] * nc.y() + nn[2] * nc.z()), 1.0, 1e-5);
            } else if (inside) {
                ++missed;
            }
        }
    EXPECT_GT(covered, 20000);
    EXPECT_EQ(missed, 0);
    EXPECT_LT(worst, 1e-6);
}

TEST(Rasterizer, SpherePixelsBackProjectOntoTheSphere) {
    const io::SensorSpec spec = kinect_v2_spec("k");
    const Eigen::Vector3d centre(0, 0, 1.3);
    const double radius = 0.1;
    Mesh mesh;
    testing::add_icosphere(mesh, centre, radius, 6);  // sagitta < 4e-6 m
    const Pose world_from_camera = look_at(Eigen::Vector3d(1.5, 0.2, 1.6), centre);
    const DepthRender r = render_depth(RenderScene(mesh), spec.depth, world_from_camera);
    long valid = 0;
    double worst = 0;
    for (int row = 0; row < r.depth.rows; ++row)
        for (int col = 0; col < r.depth.cols; ++col) {
            const double z = r.depth.at<double>(row, col);
            if (!std::isfinite(z)) continue;
            ++valid;
            const Eigen::Vector3d p = world_from_camera * spec.depth.unproject(col, row, z);
            worst = std::max(worst, std::abs((p - centre).norm() - radius));
        }
    // Expected silhouette area: pi (f r / d)^2 pixels, d ~ 1.52 m.
    const double d = (world_from_camera.translation() - centre).norm();
    const double expected = M_PI * std::pow(365.5 * radius / d, 2);
    EXPECT_NEAR(valid, expected, 0.05 * expected);
    EXPECT_LT(worst, 1e-5);
}

TEST(Rasterizer, ColourCameraResolvesItsOwnOcclusions) {
    // Depth camera at the origin looking along +z; sphere in front of a plane.
    const io::SensorSpec spec = kinect_v2_spec("k");
    const Eigen::Vector3d centre(0, 0, 1.0);
    const double radius = 0.1;
    // The wall is triangles 0 and 1.
    const Mesh mesh = testing::ball_before_wall(Eigen::Vector3d(0, 0, 1.5), 1.0, centre, radius, 5);
    const RenderScene scene(mesh);
    const Pose world_from_depth = Pose::Identity();
    const Pose world_from_color = world_from_depth * spec.color_from_depth.inverse();
    const Rgb green{0, 200, 0}, red{200, 0, 0};
    const DepthRender depth = render_depth(scene, spec.depth, world_from_depth);
    const cv::Mat color = render_color(
        scene, spec.color, world_from_color,
        [&](const Eigen::Vector3d&, int t) { return t < 2 ? green : red; }, Rgb{0, 0, 0});
    const Eigen::Vector3d c = world_from_color.translation();
    ASSERT_NEAR(c.x(), -0.052, 1e-12);
    long hidden = 0, seen = 0, wrong = 0;
    for (int row = 0; row < depth.depth.rows; ++row)
        for (int col = 0; col < depth.depth.cols; ++col) {
            if (depth.triangle.at<int>(row, col) != 0 && depth.triangle.at<int>(row, col) != 1)
                continue;
            const Eigen::Vector3d p =
                world_from_depth * spec.depth.unproject(col, row, depth.depth.at<double>(row, col));
            // Distance of the sphere centre from the segment colour centre -> p.
            const Eigen::Vector3d dir = (p - c).normalized();
            const double along = (centre - c).dot(dir);
            const double dist = (centre - c - along * dir).norm();
            const Eigen::Vector2d uv = spec.color.project(world_from_color.inverse() * p);
            if (!spec.color.contains(uv)) continue;
            const cv::Vec3b bgr = color.at<cv::Vec3b>(static_cast<int>(std::lround(uv.y())),
                                                      static_cast<int>(std::lround(uv.x())));
            const Rgb got{bgr[2], bgr[1], bgr[0]};
            if (dist < radius - 0.004) {
                ++hidden;
                if (!(got == red)) ++wrong;
            } else if (dist > radius + 0.004) {
                ++seen;
                if (!(got == green)) ++wrong;
            }
        }
    EXPECT_GT(hidden, 300);  // a crescent of plane pixels that only the depth camera sees
    EXPECT_GT(seen, 10000);
    EXPECT_EQ(wrong, 0);
}

TEST(Rasterizer, SameResultForAnyThreadCountAndBanding) {
    const io::SensorSpec spec = kinect_v2_spec("k");
    const Mesh mesh = testing::ball_before_wall(Eigen::Vector3d(0, 0, 1.5), 0.3,
                                                Eigen::Vector3d(0.02, 0.01, 1.1), 0.1, 4);
    const RenderScene scene(mesh);
    DepthRender one, many;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        one = render_depth(scene, spec.depth, Pose::Identity(), RasterOptions{0.05, 16});
    }
    many = render_depth(scene, spec.depth, Pose::Identity(), RasterOptions{0.05, 5});
    EXPECT_TRUE(same_bits(one.depth, many.depth));
    EXPECT_TRUE(same_bits(one.triangle, many.triangle));
    EXPECT_TRUE(same_bits(one.normal, many.normal));
}

TEST(Rasterizer, RejectsDistortionAndEmptyMeshes) {
    io::SensorSpec spec = kinect_v2_spec("k");
    Mesh mesh;
    testing::add_quad(mesh, Eigen::Vector3d(0, 0, 1.5), Eigen::Vector3d::UnitX(),
                      Eigen::Vector3d::UnitY(), 0.3);
    spec.depth.distortion = Distortion{"brown", {0.05, -0.15}};
    EXPECT_THROW(render_depth(RenderScene(mesh), spec.depth, Pose::Identity()), InputError);
    EXPECT_THROW(RenderScene{Mesh{}}, InputError);
}

}  // namespace
}  // namespace rgbd::synth
