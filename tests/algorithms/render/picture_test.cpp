// Pictures of known geometry (algorithms/render/picture.hpp): a sphere's silhouette matches the
// exact projection of the sphere, vertex colours and grey shading appear where they should,
// points are splatted with a depth test, and the heat map colours match the colour bar.
#include "algorithms/render/picture.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "tests/validation/synth_test_shapes.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
using namespace rgbd::render;

namespace {

const Eigen::Vector3d kCentre(0.1, -0.05, 0.3);
constexpr double kRadius = 0.2;

Geometry sphere_geometry(int levels = 4) {
    Mesh mesh;
    synth::testing::add_icosphere(mesh, kCentre, kRadius, levels);
    return from_mesh(mesh);
}

/// Pixels whose ray through the pixel centre hits the true sphere.
cv::Mat exact_silhouette(const Camera& cam) {
    const auto& k = cam.intrinsics;
    const Eigen::Vector3d c = cam.world_from_camera.inverse() * kCentre;
    cv::Mat mask(k.height, k.width, CV_8UC1);
    for (int r = 0; r < k.height; ++r)
        for (int col = 0; col < k.width; ++col) {
            const Eigen::Vector3d d =
                Eigen::Vector3d((col - k.cx) / k.fx, (r - k.cy) / k.fy, 1.0).normalized();
            const double along = c.dot(d);
            mask.at<std::uint8_t>(r, col) = (c - along * d).norm() <= kRadius ? 255 : 0;
        }
    return mask;
}

cv::Mat covered(const Picture& pic, Rgb background = {255, 255, 255}) {
    const cv::Mat model = pic.image(pic.model_area);
    cv::Mat mask(model.rows, model.cols, CV_8UC1);
    for (int r = 0; r < model.rows; ++r)
        for (int c = 0; c < model.cols; ++c)
            mask.at<std::uint8_t>(r, c) =
                model.at<cv::Vec3b>(r, c) != cv::Vec3b(background.b, background.g, background.r)
                    ? 255
                    : 0;
    return mask;
}

Eigen::Vector2d centroid(const cv::Mat& mask) {
    const cv::Moments m = cv::moments(mask, true);
    return {m.m10 / m.m00, m.m01 / m.m00};
}

CameraOptions front_view(int w = 320, int h = 240) {
    CameraOptions o;
    o.width = w;
    o.height = h;
    o.view = ViewDirection::kFront;
    return o;
}

}  // namespace

TEST(Picture, SphereSilhouetteMatchesTheExactProjection) {
    const Geometry g = sphere_geometry();
    for (const ViewDirection view :
         {ViewDirection::kFront, ViewDirection::kAuto, ViewDirection::kTop, ViewDirection::kLeft}) {
        CameraOptions o = front_view();
        o.view = view;
        const Camera cam = fit_camera(g.vertices, Orientation{}, o);
        const Picture pic = render_picture(g, cam);
        const cv::Mat got = covered(pic), want = exact_silhouette(cam);
        const double n_want = cv::countNonZero(want), n_got = cv::countNonZero(got);
        ASSERT_GT(n_want, 1000);
        EXPECT_EQ(pic.covered_pixels, static_cast<std::size_t>(n_got));
        // The icosphere (level 4) is inscribed: slightly smaller, never larger.
        EXPECT_NEAR(n_got / n_want, 0.995, 0.01) << int(view);
        cv::Mat diff;
        cv::bitwise_xor(got, want, diff);
        EXPECT_LT(cv::countNonZero(diff), 0.02 * n_want) << int(view);
        EXPECT_LT((centroid(got) - centroid(want)).norm(), 0.5) << int(view);
        // Fitted: the sphere fills the height less the margins (5% each side), centred.
        cv::Rect box = cv::boundingRect(got);
        EXPECT_NEAR(box.height, 0.9 * 240, 3) << int(view);
        EXPECT_NEAR(box.y + 0.5 * box.height, 119.5, 1.5) << int(view);
        EXPECT_NEAR(box.x + 0.5 * box.width, 159.5, 1.5) << int(view);
    }
}

TEST(Picture, ViewDirectionsLookFromWhereTheySay) {
    const Geometry g = sphere_geometry(1);
    Orientation o;  // up +y, front +z
    auto camera_position = [&](ViewDirection v) {
        CameraOptions opt = front_view();
        opt.view = v;
        return Eigen::Vector3d(fit_camera(g.vertices, o, opt).world_from_camera.translation() -
                               kCentre);
    };
    EXPECT_GT(camera_position(ViewDirection::kFront).normalized().z(), 0.999);
    EXPECT_LT(camera_position(ViewDirection::kBack).normalized().z(), -0.999);
    EXPECT_GT(camera_position(ViewDirection::kRight).normalized().x(), 0.999);
    EXPECT_LT(camera_position(ViewDirection::kLeft).normalized().x(), -0.999);
    EXPECT_GT(camera_position(ViewDirection::kTop).normalized().y(), 0.999);
    const Eigen::Vector3d a = camera_position(ViewDirection::kAuto).normalized();
    EXPECT_NEAR(std::asin(a.y()) * 180 / M_PI, 20.0, 1e-6);
    EXPECT_NEAR(std::atan2(a.x(), a.z()) * 180 / M_PI, 35.0, 1e-6);
    // Image up is world up in the front view: the camera's y axis points down (-y).
    CameraOptions opt = front_view();
    const Camera cam = fit_camera(g.vertices, o, opt);
    EXPECT_LT(cam.world_from_camera.linear().col(1).y(), -0.999);
}

TEST(Picture, OrientationFollowsTheSensors) {
    // Three sensors in front of the object (+x side), upright with world up = +z.
    std::vector<Pose> sensors;
    for (double y : {-0.3, 0.0, 0.3}) {
        Pose p = Pose::Identity();
        // camera z (forward) = -x, camera y (down) = -z, camera x = z_c x ... right-handed
        p.linear().col(2) = Eigen::Vector3d(-1, 0, 0);
        p.linear().col(1) = Eigen::Vector3d(0, 0, -1);
        p.linear().col(0) = p.linear().col(1).cross(p.linear().col(2));
        p.translation() = Eigen::Vector3d(1.5, y, 0.2);
        sensors.push_back(p);
    }
    const Orientation o = guess_orientation(sensors, Eigen::Vector3d::Zero(), std::nullopt);
    EXPECT_GT(o.up.z(), 0.999);
    EXPECT_GT(o.front.x(), 0.999);
    const Orientation given =
        guess_orientation(sensors, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 2, 0));
    EXPECT_GT(given.up.y(), 0.999);
    EXPECT_NEAR(given.front.dot(given.up), 0.0, 1e-12);
    EXPECT_THROW(guess_orientation({}, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()),
                 InputError);
}

// sensors_up (toolkit/pose.hpp), which the orientation and rgbd-mesh --watertight share: the
// mean image-up of the sensors; nothing when there are none or they disagree.
TEST(Picture, SensorsUpNeedsAgreement) {
    EXPECT_FALSE(sensors_up({}).has_value());
    Pose upright = Pose::Identity();  // camera y (down) = -z
    upright.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;
    Pose upside_down = Pose::Identity();
    upside_down.linear() << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    const auto up = sensors_up({upright, upright});
    ASSERT_TRUE(up.has_value());
    EXPECT_NEAR(up->z(), 1.0, 1e-12);
    EXPECT_FALSE(sensors_up({upright, upside_down}).has_value());
    Pose tilted = upright;  // 60 degrees of roll: agreement cos(30) with the upright one
    tilted.linear() = Eigen::AngleAxisd(M_PI / 3, Eigen::Vector3d::UnitY()) * upright.linear();
    EXPECT_TRUE(sensors_up({upright, tilted}, 0.7).has_value());
    EXPECT_FALSE(sensors_up({upright, tilted}, 0.9).has_value());
}

TEST(Picture, GreyShadingAndVertexColours) {
    Geometry g = sphere_geometry();
    const Camera cam = fit_camera(g.vertices, Orientation{}, front_view());
    // Grey: every covered pixel is grey, and the light (above-left) makes the upper left
    // brighter than the lower right.
    {
        const Picture pic = render_picture(g, cam);
        double upper_left = 0, lower_right = 0;
        for (int r = 0; r < 240; ++r)
            for (int c = 0; c < 320; ++c) {
                const cv::Vec3b p = pic.image.at<cv::Vec3b>(r, c);
                if (p == cv::Vec3b(255, 255, 255)) continue;
                ASSERT_TRUE(p[0] == p[1] && p[1] == p[2]);
                if (r < 100 && c < 140) upper_left = std::max<double>(upper_left, p[0]);
                if (r > 140 && c > 180) lower_right = std::max<double>(lower_right, p[0]);
            }
        EXPECT_GT(upper_left, lower_right + 40);
    }
    // Colours: the upper half (y above the centre) red, the lower half blue.
    for (const auto& v : g.vertices)
        g.colors.push_back(v.y() > kCentre.y() ? Rgb{220, 20, 20} : Rgb{20, 20, 220});
    const Picture pic = render_picture(g, cam);
    const cv::Vec3b top = pic.image.at<cv::Vec3b>(60, 160),
                    bottom = pic.image.at<cv::Vec3b>(180, 160);
    EXPECT_GT(top[2], 2 * top[0]) << top;           // BGR: red dominates
    EXPECT_GT(bottom[0], 2 * bottom[2]) << bottom;  // blue dominates
}

TEST(Picture, PointsAreSplattedWithADepthTest) {
    // A Fibonacci sphere of points with outward normals: front hemisphere red, back blue.
    Geometry g;
    const int n = 20000;
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - (2.0 * i + 1.0) / n;
        const double r = std::sqrt(1 - z * z), phi = i * M_PI * (3.0 - std::sqrt(5.0));
        const Eigen::Vector3d d(r * std::cos(phi), r * std::sin(phi), z);
        g.vertices.push_back(kCentre + kRadius * d);
        g.normals.push_back(d);
        g.colors.push_back(z > 0 ? Rgb{255, 0, 0} : Rgb{0, 0, 255});
    }
    const Camera cam = fit_camera(g.vertices, Orientation{}, front_view());
    const Picture pic = render_picture(g, cam);
    const cv::Mat got = covered(pic), want = exact_silhouette(cam);
    const double n_want = cv::countNonZero(want);
    EXPECT_NEAR(cv::countNonZero(got) / n_want, 1.0, 0.06);
    EXPECT_LT((centroid(got) - centroid(want)).norm(), 1.0);
    // No hole in the middle: the disc around the centre is fully covered.
    const Eigen::Vector2d c = centroid(want);
    int holes = 0, blue = 0;
    for (int r = 0; r < 240; ++r)
        for (int col = 0; col < 320; ++col) {
            const cv::Vec3b p = pic.image.at<cv::Vec3b>(r, col);
            if ((Eigen::Vector2d(col, r) - c).norm() < 80 && p == cv::Vec3b(255, 255, 255)) ++holes;
            blue += p == cv::Vec3b(255, 0, 0);
        }
    EXPECT_EQ(holes, 0);
    // The back hemisphere is hidden, except where the two meet at the silhouette.
    EXPECT_LT(blue, 0.02 * n_want);
    // Grey points by their normals, no colours: all grey.
    g.colors.clear();
    const Picture grey = render_picture(g, cam);
    const cv::Vec3b p = grey.image.at<cv::Vec3b>(int(c.y()), int(c.x()));
    EXPECT_TRUE(p[0] == p[1] && p[1] == p[2] && p[0] < 255);
}

TEST(Picture, HeatMapColoursMatchTheColourBar) {
    // A square facing the camera with value = x, from -0.5 to 0.5.
    Geometry g;
    g.vertices = {{-0.5, -0.5, 0}, {0.5, -0.5, 0}, {0.5, 0.5, 0}, {-0.5, 0.5, 0}};
    g.triangles = {{0, 1, 2}, {0, 2, 3}};
    for (const auto& v : g.vertices) g.scalars.push_back(v.x());
    const Camera cam = fit_camera(g.vertices, Orientation{}, front_view(300, 300));
    PictureOptions opt;
    opt.scalar_min = -0.5;
    opt.scalar_max = 0.5;
    const Picture pic = render_picture(g, cam, opt);
    ASSERT_TRUE(pic.color_bar.has_value());
    EXPECT_GT(pic.image.cols, 300);  // the bar strip is appended
    EXPECT_EQ(pic.model_area, cv::Rect(0, 0, 300, 300));
    const cv::Rect bar = *pic.color_bar;
    EXPECT_GE(bar.x, 300);
    const Pose camera_from_world = cam.world_from_camera.inverse();
    const auto& k = cam.intrinsics;
    int checked = 0;
    for (int col = 20; col < 280; col += 13) {
        const int row = 150;
        // The point of the plane z = 0 seen by this pixel.
        const Eigen::Vector3d dir_cam((col - k.cx) / k.fx, (row - k.cy) / k.fy, 1.0);
        const Eigen::Vector3d o = cam.world_from_camera.translation();
        const Eigen::Vector3d d = cam.world_from_camera.linear() * dir_cam;
        const Eigen::Vector3d hit = o - o.z() / d.z() * d;
        (void)camera_from_world;
        if (std::abs(hit.x()) > 0.49 || std::abs(hit.y()) > 0.49) continue;
        const double t = hit.x() + 0.5;
        const Rgb want = heat_color(t);
        const cv::Vec3b got = pic.image.at<cv::Vec3b>(row, col);
        EXPECT_LE(std::abs(got[2] - want.r) + std::abs(got[1] - want.g) + std::abs(got[0] - want.b),
                  30)
            << "t " << t;
        // The colour bar shows the same colour at the height of that value.
        const int bar_row = bar.y + static_cast<int>(std::lround((1 - t) * (bar.height - 1)));
        const cv::Vec3b b = pic.image.at<cv::Vec3b>(bar_row, bar.x + bar.width / 2);
        EXPECT_LE(std::abs(b[2] - want.r) + std::abs(b[1] - want.g) + std::abs(b[0] - want.b), 12)
            << "bar at t " << t;
        ++checked;
    }
    EXPECT_GT(checked, 15);
    // The ends of the bar are the ends of the colour map.
    const Rgb lo = heat_color(0), hi = heat_color(1);
    EXPECT_EQ(pic.image.at<cv::Vec3b>(bar.y, bar.x + 1), cv::Vec3b(hi.b, hi.g, hi.r));
    EXPECT_EQ(pic.image.at<cv::Vec3b>(bar.y + bar.height - 1, bar.x + 1),
              cv::Vec3b(lo.b, lo.g, lo.r));
    EXPECT_NE(lo, hi);
}

TEST(Picture, SameResultForAnyThreadCount) {
    const Geometry g = sphere_geometry(3);
    const Camera cam = fit_camera(g.vertices, Orientation{}, CameraOptions{});
    const Picture a = render_picture(g, cam);
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    const Picture b = render_picture(g, cam);
    EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_INF), 0.0);
}

// from_views: every live point of every view in view order, moved by its view's pose when the
// view is in its sensor frame, with its colour and rotated normal; the sensors of posed views.
TEST(Picture, FromViewsPlacesEveryLivePointInViewOrder) {
    std::vector<PointCloud> views(3);
    std::vector<Eigen::Vector3d> expected_points, expected_normals;
    std::vector<Rgb> expected_colours;
    for (std::size_t v = 0; v < views.size(); ++v) {
        PointCloud& view = views[v];
        Pose world_from_sensor = Pose::Identity();
        world_from_sensor.linear() =
            Eigen::AngleAxisd(0.3 * double(v + 1), Eigen::Vector3d::UnitY()).toRotationMatrix();
        world_from_sensor.translation() = Eigen::Vector3d(0.1 * double(v), 0.2, -0.3);
        view.view.world_from_sensor = world_from_sensor;
        // View 1 is already in the world frame: drawn as it is.
        view.view.frame = v == 1 ? ViewFrame::kWorld : ViewFrame::kSensor;
        view.points.add_normal_map();
        auto colours = view.add_colors();
        for (int i = 0; i < 1000 + 300 * int(v); ++i) {
            const Eigen::Vector3d p(0.001 * i, std::sin(0.01 * i), 1.0 + 0.1 * double(v));
            const Eigen::Vector3d n = Eigen::Vector3d(1.0, 0.5 * double(v), 0.2 * i).normalized();
            const Rgb c{std::uint8_t(i % 256), std::uint8_t(v * 40), std::uint8_t(i / 256)};
            const auto idx = *view.points.insert(to_point(p), to_vector(n));
            colours.set(idx, c);
            if (i % 7 == 3) {
                view.points.remove(idx);  // removed points are not drawn
                continue;
            }
            const Pose& pose = v == 1 ? Pose::Identity() : world_from_sensor;
            expected_points.push_back(pose * p);
            expected_normals.push_back(pose.linear() * n);
            expected_colours.push_back(c);
        }
    }
    const Geometry g = from_views(views);
    ASSERT_EQ(g.vertices.size(), expected_points.size());
    ASSERT_EQ(g.normals.size(), expected_points.size());
    ASSERT_EQ(g.colors.size(), expected_points.size());
    for (std::size_t a = 0; a < expected_points.size(); ++a) {
        ASSERT_LT((g.vertices[a] - expected_points[a]).norm(), 1e-12) << "point " << a;
        ASSERT_LT((g.normals[a] - expected_normals[a]).norm(), 1e-6) << "point " << a;
        ASSERT_EQ(g.colors[a].r, expected_colours[a].r) << "point " << a;
        ASSERT_EQ(g.colors[a].g, expected_colours[a].g) << "point " << a;
        ASSERT_EQ(g.colors[a].b, expected_colours[a].b) << "point " << a;
    }
    EXPECT_EQ(g.sensors.size(), 3u);
    // A view without colours: no colours at all.
    views.push_back(PointCloud());
    views.back().points.add_normal_map();
    views.back().points.insert(to_point(Eigen::Vector3d(0, 0, 1)),
                               to_vector(Eigen::Vector3d(0, 0, 1)));
    EXPECT_TRUE(from_views(views).colors.empty());
    EXPECT_EQ(from_views(views).vertices.size(), expected_points.size() + 1);
}

TEST(Picture, RejectsBadInput) {
    const Geometry sphere = sphere_geometry(1);
    const Camera cam = fit_camera(sphere.vertices, Orientation{}, front_view());
    EXPECT_THROW(render_picture(Geometry{}, cam), InputError);
    Geometry nan = sphere;
    nan.vertices[3].x() = std::nan("");
    EXPECT_THROW(render_picture(nan, cam), InputError);
    Geometry bad_index = sphere;
    bad_index.triangles[0][1] = 100000;
    EXPECT_THROW(render_picture(bad_index, cam), InputError);
    Geometry short_colors = sphere;
    short_colors.colors.resize(3);
    EXPECT_THROW(render_picture(short_colors, cam), InputError);
    Geometry nan_value = sphere;
    nan_value.scalars.assign(sphere.vertices.size(), std::nan(""));
    EXPECT_THROW(render_picture(nan_value, cam), InputError);
    PictureOptions bad_range;
    bad_range.scalar_min = 1;
    bad_range.scalar_max = 0;
    EXPECT_THROW(render_picture(sphere, cam, bad_range), InputError);
    CameraOptions o;
    o.width = 0;
    EXPECT_THROW(fit_camera(sphere.vertices, Orientation{}, o), InputError);
    o = CameraOptions{};
    o.elevation_deg = 100;
    EXPECT_THROW(fit_camera(sphere.vertices, Orientation{}, o), InputError);
    EXPECT_THROW(
        fit_camera({Eigen::Vector3d::Constant(std::nan(""))}, Orientation{}, CameraOptions{}),
        InputError);
    EXPECT_THROW(parse_view_direction("diagonal"), InputError);
    EXPECT_EQ(parse_view_direction("top"), ViewDirection::kTop);
}
