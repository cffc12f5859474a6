// Tests of depth_to_cloud on synthetic frames rendered analytically in the test: a textured
// tilted plane (geometry and colour), a sphere in front of a plane (colour occlusion), depth
// window, mask, invalid depth and invalid intrinsics.
#include "algorithms/frames/depth_to_cloud.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <set>

#include "tests/support/input_error.hpp"
#include "toolkit/error.hpp"

namespace rgbd::frames {
namespace {

using rgbd::test::expect_input_error;

constexpr double kPi = 3.14159265358979323846;

/// A centred pinhole camera of width x height pixels and focal length f, times `scale`, with
/// Brown distortion `coeffs` when `distorted`.
PinholeIntrinsics camera(int width, int height, double f, int scale, bool distorted,
                         const std::vector<double>& coeffs) {
    PinholeIntrinsics k;
    k.width = width * scale;
    k.height = height * scale;
    k.fx = k.fy = f * scale;
    k.cx = (k.width - 1) / 2.0;
    k.cy = (k.height - 1) / 2.0;
    if (distorted) {
        k.distortion.model = "brown";
        k.distortion.coeffs = coeffs;
    }
    return k;
}

PinholeIntrinsics depth_camera(bool distorted, int scale = 1) {
    return camera(160, 120, 130.0, scale, distorted, {0.05, -0.02, 0.001, -0.0005, 0.0});
}

PinholeIntrinsics color_camera(bool distorted, int scale = 1) {
    return camera(480, 360, 390.0, scale, distorted, {-0.03, 0.01, 0.0, 0.0, 0.0});
}

/// Smooth texture of the plane, a function of the depth-frame 3D point.
Eigen::Vector3d texture(const Eigen::Vector3d& x) {
    return {128.0 + 90.0 * std::sin(2 * kPi * x.x() / 0.25),
            128.0 + 90.0 * std::cos(2 * kPi * x.y() / 0.2),
            128.0 + 60.0 * std::sin(2 * kPi * (x.x() + x.y()) / 0.3)};
}

struct Plane {
    Eigen::Vector3d n = Eigen::Vector3d(0.3, 0.2, 1.0).normalized();
    double d = n.dot(Eigen::Vector3d(0, 0, 1.5));
};

/// Tilted textured plane at 1.5 m, both cameras distorted, 52 mm baseline, 1 degree yaw.
RgbdFrame plane_frame(const Plane& plane) {
    RgbdFrame f;
    f.depth_intrinsics = depth_camera(true);
    f.color_intrinsics = color_camera(true);
    f.color_from_depth = Eigen::Translation3d(0.052, 0.0, 0.0) *
                         Eigen::AngleAxisd(1.0 * kPi / 180.0, Eigen::Vector3d::UnitY());
    f.depth = cv::Mat(120, 160, CV_32FC1);
    for (int v = 0; v < 120; ++v)
        for (int u = 0; u < 160; ++u) {
            const Eigen::Vector3d ray = f.depth_intrinsics.unproject(u, v, 1.0);
            f.depth.at<float>(v, u) = static_cast<float>(plane.d / plane.n.dot(ray));
        }
    const Pose d_from_c = f.color_from_depth.inverse();
    f.color = cv::Mat(360, 480, CV_8UC3);
    for (int v = 0; v < 360; ++v)
        for (int u = 0; u < 480; ++u) {
            const Eigen::Vector3d o = d_from_c.translation();
            const Eigen::Vector3d dir = d_from_c.linear() * f.color_intrinsics.unproject(u, v, 1.0);
            const double t = (plane.d - plane.n.dot(o)) / plane.n.dot(dir);
            const Eigen::Vector3d c = texture(o + t * dir);
            f.color.at<cv::Vec3b>(v, u) =
                cv::Vec3b(cv::saturate_cast<uchar>(c.z()), cv::saturate_cast<uchar>(c.y()),
                          cv::saturate_cast<uchar>(c.x()));
        }
    f.sensor_id = "k2-test";
    f.frame_index = 7;
    f.timestamp_ns = 123456789;
    f.source = "synthetic/plane";
    f.world_from_sensor = Eigen::Translation3d(1.0, 2.0, 3.0) * Pose::Identity();
    f.has_pose = true;
    return f;
}

TEST(DepthToCloud, PlanePointsAndColours) {
    const Plane plane;
    const RgbdFrame frame = plane_frame(plane);
    Report report;
    const PointCloud cloud = depth_to_cloud(frame, CloudOptions{}, &report);
    ASSERT_EQ(cloud.size(), 160u * 120u);
    EXPECT_EQ(cloud.view.grid_width, 160);
    EXPECT_EQ(cloud.view.grid_height, 120);
    EXPECT_EQ(cloud.view.frame, ViewFrame::kSensor);
    EXPECT_EQ(cloud.view.sensor, "k2-test");
    EXPECT_EQ(cloud.view.time_ns, 123456789);
    EXPECT_EQ(cloud.view.source, "synthetic/plane");
    ASSERT_TRUE(cloud.view.intrinsics.has_value());
    EXPECT_TRUE(*cloud.view.intrinsics == frame.depth_intrinsics);
    ASSERT_TRUE(cloud.view.world_from_sensor.has_value());
    EXPECT_TRUE(cloud.view.world_from_sensor->isApprox(frame.world_from_sensor));

    const auto colors = cloud.colors();
    const auto pixel = cloud.pixel_map();
    const auto conf = cloud.float_map(prop::kConfidence);
    const auto flag = cloud.flag(kUncoloured);
    ASSERT_TRUE(pixel && conf && flag);
    double max_plane_error = 0.0, max_color_error = 0.0;
    std::size_t compared = 0;
    std::uint32_t expected_pixel = 0;
    for (PointSet::Index idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        max_plane_error = std::max(max_plane_error, std::abs(plane.n.dot(p) - plane.d));
        EXPECT_EQ((*pixel)[idx], expected_pixel++);
        EXPECT_EQ((*conf)[idx], 1.0f);
        // The pixel ray through the point.
        const int u = int((*pixel)[idx] % 160), v = int((*pixel)[idx] / 160);
        const Eigen::Vector3d ray = frame.depth_intrinsics.unproject(u, v, 1.0);
        EXPECT_LT((p / p.z() - ray).norm(), 1e-9);
        if ((*flag)[idx]) continue;  // outside the colour image
        // Away from the border of the colour image (bilinear taps clamped there).
        const Eigen::Vector2d uv = frame.color_intrinsics.project(frame.color_from_depth * p);
        if (uv.x() < 1.0 || uv.y() < 1.0 || uv.x() > 478.0 || uv.y() > 358.0) continue;
        const Eigen::Vector3d expected = texture(p);
        const Rgb c = colors.get(idx);
        const Eigen::Vector3d got(c.r, c.g, c.b);
        const double err = (got - expected).cwiseAbs().maxCoeff();
        if (err > max_color_error && std::getenv("RGBD_DEBUG"))
            std::printf("err %.2f at u %d v %d\n", err, u, v);
        max_color_error = std::max(max_color_error, err);
        ++compared;
    }
    EXPECT_LT(max_plane_error, 1e-6);
    EXPECT_GT(compared, cloud.size() * 9 / 10);
    EXPECT_LE(max_color_error, 1.5) << "colour differs from the texture at the true point";
    EXPECT_EQ(report["points"].get<std::size_t>(), cloud.size());
    EXPECT_EQ(report["uncoloured_hidden"].get<std::size_t>(), 0u);
    RecordProperty("max_color_error", std::to_string(max_color_error));
}

/// Ray / sphere intersection: smallest t > 0 or nullopt.
std::optional<double> hit_sphere(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                 const Eigen::Vector3d& c, double r) {
    const Eigen::Vector3d oc = o - c;
    const double a = d.dot(d), b = 2 * oc.dot(d), cc = oc.dot(oc) - r * r;
    const double disc = b * b - 4 * a * cc;
    if (disc < 0) return std::nullopt;
    const double t = (-b - std::sqrt(disc)) / (2 * a);
    if (t <= 0) return std::nullopt;
    return t;
}

struct SphereScene {
    Eigen::Vector3d centre{0.0, 0.0, 1.0};
    double radius = 0.15;
    double plane_z = 1.5;
    cv::Vec3b sphere_bgr{30, 30, 220};
    cv::Vec3b plane_bgr{40, 200, 40};
};

RgbdFrame sphere_frame(const SphereScene& s) {
    RgbdFrame f;
    f.depth_intrinsics = depth_camera(false, 2);
    f.color_intrinsics = color_camera(false, 2);
    f.color_from_depth = Eigen::Translation3d(0.052, 0.0, 0.0) * Pose::Identity();
    f.depth = cv::Mat(f.depth_intrinsics.height, f.depth_intrinsics.width, CV_32FC1);
    for (int v = 0; v < f.depth.rows; ++v)
        for (int u = 0; u < f.depth.cols; ++u) {
            const Eigen::Vector3d ray = f.depth_intrinsics.unproject(u, v, 1.0);
            const auto t = hit_sphere(Eigen::Vector3d::Zero(), ray, s.centre, s.radius);
            f.depth.at<float>(v, u) = static_cast<float>(t ? *t : s.plane_z);
        }
    const Eigen::Vector3d o = f.color_from_depth.inverse().translation();
    f.color = cv::Mat(f.color_intrinsics.height, f.color_intrinsics.width, CV_8UC3);
    for (int v = 0; v < f.color.rows; ++v)
        for (int u = 0; u < f.color.cols; ++u) {
            const Eigen::Vector3d ray = f.color_intrinsics.unproject(u, v, 1.0);
            f.color.at<cv::Vec3b>(v, u) =
                hit_sphere(o, ray, s.centre, s.radius) ? s.sphere_bgr : s.plane_bgr;
        }
    return f;
}

TEST(DepthToCloud, OcclusionFlagsHiddenPlanePoints) {
    const SphereScene scene;
    const RgbdFrame frame = sphere_frame(scene);
    Report report;
    const PointCloud cloud = depth_to_cloud(frame, CloudOptions{}, &report);
    ASSERT_EQ(cloud.size(), 320u * 240u);
    const auto colors = cloud.colors();
    const auto flag = *cloud.flag(kUncoloured);
    std::size_t outside = 0;
    const Eigen::Vector3d o = frame.color_from_depth.inverse().translation();
    std::size_t hidden = 0, hidden_flagged = 0, flagged_visible = 0, sphere_points = 0,
                sphere_ok = 0, sphere_flagged = 0;
    auto near = [](Rgb c, cv::Vec3b bgr, int tol) {
        return std::abs(c.r - bgr[2]) <= tol && std::abs(c.g - bgr[1]) <= tol &&
               std::abs(c.b - bgr[0]) <= tol;
    };
    for (PointSet::Index idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        const Rgb c = colors.get(idx);
        const bool on_plane = std::abs(p.z() - scene.plane_z) < 1e-5;
        if (!on_plane) {
            ++sphere_points;
            sphere_ok += near(c, scene.sphere_bgr, 2);
            sphere_flagged += flag[idx];
            continue;
        }
        // Truth: the segment from the colour camera to the point crosses the sphere.
        const auto t = hit_sphere(o, p - o, scene.centre, scene.radius);
        const bool is_hidden = t && *t < 1.0;
        if (!frame.color_intrinsics.contains(
                frame.color_intrinsics.project(frame.color_from_depth * p))) {
            ++outside;
            EXPECT_TRUE(flag[idx]);
            continue;
        }
        hidden += is_hidden;
        hidden_flagged += is_hidden && flag[idx];
        flagged_visible += !is_hidden && flag[idx];
        // No plane point, flagged or not, takes the sphere's colour.
        EXPECT_TRUE(near(c, scene.plane_bgr, 2))
            << "plane point " << p.transpose() << " has colour " << int(c.r) << " " << int(c.g)
            << " " << int(c.b) << (flag[idx] ? " (flagged)" : "");
    }
    EXPECT_GT(hidden, 150u);
    EXPECT_EQ(hidden_flagged, hidden)
        << "every plane point hidden from the colour camera is flagged";
    // The splat margin flags at most a thin band of visible points along the shadow.
    EXPECT_LT(flagged_visible, hidden / 2 + 20);
    EXPECT_GE(sphere_ok, sphere_points * 98 / 100);
    // A few grazing sphere points at the limb may hide behind their neighbours' splats.
    EXPECT_LT(sphere_flagged, sphere_points / 100);
    EXPECT_EQ(report["uncoloured_hidden"].get<std::size_t>(),
              hidden_flagged + flagged_visible + sphere_flagged);
    EXPECT_EQ(report["uncoloured_outside"].get<std::size_t>(), outside);
    if (std::getenv("RGBD_DEBUG"))
        std::printf("hidden %zu flagged %zu flagged_visible %zu sphere %zu/%zu outside %zu\n",
                    hidden, hidden_flagged, flagged_visible, sphere_ok, sphere_points, outside);
    RecordProperty("hidden", std::to_string(hidden));
    RecordProperty("flagged_visible", std::to_string(flagged_visible));
}

// Without CloudOptions::colour_hidden the points the colour camera does not see keep the
// fallback grey (flagged); colour_uncoloured() then gives them the colours depth_to_cloud
// would have; on a cloud cut to the sphere, only the sphere's points colour them.
TEST(DepthToCloud, HiddenPointsColouredLater) {
    const SphereScene scene;
    const RgbdFrame frame = sphere_frame(scene);
    const PointCloud direct = depth_to_cloud(frame, CloudOptions{});
    CloudOptions later;
    later.colour_hidden = false;
    PointCloud deferred = depth_to_cloud(frame, later);
    ASSERT_EQ(deferred.size(), direct.size());
    const auto flag = *deferred.flag(kUncoloured);
    std::size_t flagged = 0;
    for (PointSet::Index idx : deferred.points) {
        if (!flag[idx]) continue;
        ++flagged;
        const Rgb c = deferred.colors().get(idx);
        EXPECT_TRUE(c.r == 128 && c.g == 128 && c.b == 128);
    }
    ASSERT_GT(flagged, 150u);
    EXPECT_EQ(colour_uncoloured(deferred, Rgb{128, 128, 128}), flagged);
    for (PointSet::Index idx : deferred.points) {
        const Rgb a = deferred.colors().get(idx), b = direct.colors().get(idx);
        EXPECT_TRUE(a.r == b.r && a.g == b.g && a.b == b.b);
    }
    // Cut to the sphere and a band of plane around it: the hidden plane points there take the
    // nearest seen point's colour among what is left, which is never farther than before.
    PointCloud cut = depth_to_cloud(frame, later);
    const auto kept = [&](PointSet::Index idx) {
        const Eigen::Vector3d p = to_eigen(cut.points.point(idx));
        return (p - scene.centre).norm() < scene.radius + 0.05;
    };
    std::vector<PointSet::Index> drop;
    for (PointSet::Index idx : cut.points)
        if (!kept(idx)) drop.push_back(idx);
    for (auto idx : drop) cut.points.remove(idx);
    cut.points.collect_garbage();
    const std::size_t left = std::count_if(cut.points.begin(), cut.points.end(),
                                           [&](auto idx) { return (*cut.flag(kUncoloured))[idx]; });
    EXPECT_EQ(colour_uncoloured(cut, Rgb{128, 128, 128}), left);
    // An empty cloud and a cloud without the flag are left alone.
    PointCloud empty;
    EXPECT_EQ(colour_uncoloured(empty, Rgb{1, 2, 3}), 0u);
}

TEST(DepthToCloud, WithoutVisibilityTestHiddenPointsTakeSphereColour) {
    // Control for the test above: the scene really has colour bleeding without the z-buffer.
    const SphereScene scene;
    const RgbdFrame frame = sphere_frame(scene);
    CloudOptions options;
    options.visibility_test = false;
    const PointCloud cloud = depth_to_cloud(frame, options);
    const auto colors = cloud.colors();
    std::size_t bled = 0;
    for (PointSet::Index idx : cloud.points) {
        if (std::abs(cloud.points.point(idx).z() - scene.plane_z) > 1e-5) continue;
        bled += colors.get(idx).r > 150;
    }
    EXPECT_GT(bled, 50u);
}

RgbdFrame ramp_frame() {
    RgbdFrame f;
    f.depth_intrinsics = depth_camera(false);
    f.depth_intrinsics.width = 20;
    f.depth_intrinsics.height = 10;
    f.depth_intrinsics.cx = 9.5;
    f.depth_intrinsics.cy = 4.5;
    f.depth = cv::Mat(10, 20, CV_32FC1);
    for (int v = 0; v < 10; ++v)
        for (int u = 0; u < 20; ++u) f.depth.at<float>(v, u) = float(0.5 + 0.125 * u);
    f.depth.at<float>(3, 6) = std::numeric_limits<float>::quiet_NaN();
    f.depth.at<float>(5, 7) = 0.0f;
    f.depth.at<float>(6, 8) = std::numeric_limits<float>::infinity();
    f.mask = cv::Mat(10, 20, CV_8UC1);
    for (int v = 0; v < 10; ++v)
        for (int u = 0; u < 20; ++u) f.mask.at<uchar>(v, u) = (v % 2 == 0) ? 255 : 0;
    return f;
}

std::set<std::uint32_t> pixels_of(const PointCloud& cloud) {
    std::set<std::uint32_t> out;
    const auto pixel = *cloud.pixel_map();
    for (PointSet::Index idx : cloud.points) out.insert(pixel[idx]);
    return out;
}

TEST(DepthToCloud, DepthWindowMaskAndInvalidDepth) {
    const RgbdFrame frame = ramp_frame();
    // z = 0.5 + 0.125 col; window [1.0, 2.0] keeps cols 4..12; mask keeps even rows.
    CloudOptions options;
    options.z_min_m = 1.0;
    options.z_max_m = 2.0;
    Report report;
    PointCloud cloud = depth_to_cloud(frame, options, &report);
    std::set<std::uint32_t> expected;
    for (int v = 0; v < 10; v += 2)
        for (int u = 4; u <= 12; ++u)
            if (!(v == 6 && u == 8)) expected.insert(std::uint32_t(v * 20 + u));
    EXPECT_EQ(pixels_of(cloud), expected);
    EXPECT_FALSE(cloud.has_colors());  // no colour image
    EXPECT_EQ(report["invalid_depth"].get<int>(), 3);
    EXPECT_EQ(report["removed_depth_window"].get<int>(), 10 * 11);
    // Odd rows inside the window, less the two invalid pixels on odd rows.
    EXPECT_EQ(report["removed_mask"].get<int>(), 5 * 9 - 2);

    // Without the mask: all rows, minus the invalid pixels (NaN at (3,6), 0 at (5,7), inf at
    // (6,8)).
    options.use_mask = false;
    cloud = depth_to_cloud(frame, options);
    expected.clear();
    for (int v = 0; v < 10; ++v)
        for (int u = 4; u <= 12; ++u)
            if (!(v == 3 && u == 6) && !(v == 5 && u == 7) && !(v == 6 && u == 8))
                expected.insert(std::uint32_t(v * 20 + u));
    EXPECT_EQ(pixels_of(cloud), expected);

    // Window from the frame's sensor range when the options leave it at 0.
    RgbdFrame ranged = ramp_frame();
    ranged.mask.release();
    ranged.range_min_m = 0.75f;  // cols >= 2
    ranged.range_max_m = 1.25f;  // cols <= 6
    cloud = depth_to_cloud(ranged, CloudOptions{});
    expected.clear();
    for (int v = 0; v < 10; ++v)
        for (int u = 2; u <= 6; ++u)
            if (!(v == 3 && u == 6)) expected.insert(std::uint32_t(v * 20 + u));
    EXPECT_EQ(pixels_of(cloud), expected);
}

TEST(DepthToCloud, ConfidenceImageIsCopied) {
    RgbdFrame frame = ramp_frame();
    frame.mask.release();
    frame.confidence = cv::Mat(10, 20, CV_32FC1, cv::Scalar(0.25));
    const PointCloud cloud = depth_to_cloud(frame, CloudOptions{});
    const auto conf = *cloud.float_map(prop::kConfidence);
    for (PointSet::Index idx : cloud.points) EXPECT_EQ(conf[idx], 0.25f);
}

TEST(DepthToCloud, BadInputThrows) {
    RgbdFrame frame = ramp_frame();
    frame.depth_intrinsics.fx = std::numeric_limits<double>::quiet_NaN();
    frame.sensor_id = "k2-3";
    expect_input_error([&] { depth_to_cloud(frame, CloudOptions{}); }, {"k2-3"});
    RgbdFrame wrong_type = ramp_frame();
    wrong_type.depth.convertTo(wrong_type.depth, CV_16UC1);
    EXPECT_THROW(depth_to_cloud(wrong_type, CloudOptions{}), InputError);
    RgbdFrame wrong_mask = ramp_frame();
    wrong_mask.mask = cv::Mat(5, 5, CV_8UC1, cv::Scalar(1));
    EXPECT_THROW(depth_to_cloud(wrong_mask, CloudOptions{}), InputError);
    CloudOptions bad;
    bad.z_min_m = 2.0;
    bad.z_max_m = 1.0;
    EXPECT_THROW(depth_to_cloud(ramp_frame(), bad), InputError);
}

TEST(DepthToCloud, SameResultForOneAndManyThreads) {
    const SphereScene scene;
    const RgbdFrame frame = sphere_frame(scene);
    PointCloud one;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        one = depth_to_cloud(frame, CloudOptions{});
    }
    const PointCloud many = depth_to_cloud(frame, CloudOptions{});
    ASSERT_EQ(one.size(), many.size());
    const auto c1 = one.colors(), c2 = many.colors();
    const auto f1 = *one.flag(kUncoloured), f2 = *many.flag(kUncoloured);
    for (std::size_t i = 0; i < one.size(); ++i) {
        const PointSet::Index idx(i);
        ASSERT_EQ(one.points.point(idx), many.points.point(idx));
        ASSERT_EQ(c1.get(idx), c2.get(idx));
        ASSERT_EQ(f1[idx], f2[idx]);
    }
}

}  // namespace
}  // namespace rgbd::frames
