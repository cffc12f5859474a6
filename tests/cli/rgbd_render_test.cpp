// rgbd-render: the picture of a known ellipsoid covers exactly the pixels whose rays hit the
// ellipsoid (camera from --metrics), vertex colours and points appear, --scalar distance adds a
// colour bar, options change the picture as they say, and bad input gives one-line errors and
// no picture.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;
using rgbd::test::line_count;
using rgbd::test::Outcome;
using rgbd::test::slurp;

namespace {

const Eigen::Vector3d kRadii(0.3, 0.5, 0.25);

fs::path work() {
    static const fs::path root = [] {
        const fs::path d = rgbd::test::scratch_dir("rgbd_render_test");
        rgbd::test::write_ellipsoid_off(d / "ell.off", 96, 48, kRadii.x(), kRadii.y(), kRadii.z());
        rgbd::test::write_ellipsoid_off(
            d / "bumpy.off", 96, 48, kRadii.x(), kRadii.y(), kRadii.z(),
            [](double th, double ph) { return 1.0 + 0.05 * std::sin(4 * ph) * std::sin(th); });
        std::ofstream xyz(d / "pts.xyz");  // 4000 points on a sphere of radius 0.2 m
        for (int i = 0; i < 4000; ++i) {
            const double z = 1.0 - (2.0 * i + 1.0) / 4000, rr = std::sqrt(1 - z * z);
            const double phi = i * M_PI * (3.0 - std::sqrt(5.0));
            xyz << 0.2 * rr * std::cos(phi) << " " << 0.2 * rr * std::sin(phi) << " " << 0.2 * z
                << "\n";
        }
        return d;
    }();
    return root;
}

Outcome run(const std::string& command) { return rgbd::test::run_in(work(), command); }

struct Cam {
    double fx, fy, cx, cy;
    int w, h;
    Eigen::Matrix4d world_from_camera;
};

Cam camera_of(const nlohmann::json& m) {
    const auto& r = m["render"];
    Cam c{r["intrinsics"]["fx"],      r["intrinsics"]["fy"],    r["intrinsics"]["cx"],
          r["intrinsics"]["cy"],      r["intrinsics"]["width"], r["intrinsics"]["height"],
          Eigen::Matrix4d::Identity()};
    for (int i = 0; i < 16; ++i) c.world_from_camera(i / 4, i % 4) = r["world_from_camera"][i];
    return c;
}

/// Does the ray through pixel (col, row) hit the ellipsoid (centre 0, kRadii)?
bool hits(const Cam& c, int col, int row) {
    const Eigen::Vector3d o = c.world_from_camera.block<3, 1>(0, 3);
    const Eigen::Vector3d d = c.world_from_camera.block<3, 3>(0, 0) *
                              Eigen::Vector3d((col - c.cx) / c.fx, (row - c.cy) / c.fy, 1.0);
    const Eigen::Vector3d os = o.cwiseQuotient(kRadii), ds = d.cwiseQuotient(kRadii);
    const double a = ds.dot(ds), b = 2 * os.dot(ds), cc = os.dot(os) - 1;
    return b * b - 4 * a * cc >= 0;
}

bool background(const cv::Vec3b& p) { return p == cv::Vec3b(255, 255, 255); }

}  // namespace

TEST(RgbdRender, EllipsoidSilhouetteMatchesItsProjection) {
    for (const std::string view : {"front", "auto", "top"}) {
        SCOPED_TRACE(view);
        const Outcome r =
            run("$BIN/rgbd-render ell.off -o ell.png --width 320 --height 240 --view " + view +
                " --metrics ell.json");
        ASSERT_EQ(r.code, 0) << r.err;
        const cv::Mat img = cv::imread((work() / "ell.png").string());
        ASSERT_EQ(img.cols, 320);
        ASSERT_EQ(img.rows, 240);
        const Cam cam = camera_of(nlohmann::json::parse(slurp(work() / "ell.json")));
        int want = 0, got = 0, differ = 0;
        for (int row = 0; row < 240; ++row)
            for (int col = 0; col < 320; ++col) {
                const bool h = hits(cam, col, row), g = !background(img.at<cv::Vec3b>(row, col));
                want += h;
                got += g;
                differ += h != g;
            }
        ASSERT_GT(want, 5000);
        EXPECT_NEAR(double(got) / want, 1.0, 0.02);
        EXPECT_LT(differ, 0.03 * want);
        // Grey shading without colours.
        const cv::Vec3b centre = img.at<cv::Vec3b>(120, 160);
        EXPECT_TRUE(centre[0] == centre[1] && centre[1] == centre[2] && centre[0] < 255);
    }
}

TEST(RgbdRender, ColoursPointsAndHeatMap) {
    // A coloured mesh (ascii PLY): the left half (x < 0) green, the right half magenta.
    {
        std::ofstream ply(work() / "two.ply");
        ply << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
               "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
               "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
               "-1 -1 0 0 200 0\n1 -1 0 200 0 200\n1 1 0 200 0 200\n-1 1 0 0 200 0\n"
               "3 0 1 2\n3 0 2 3\n";
    }
    Outcome r = run("$BIN/rgbd-render two.ply -o two.png --view front --width 200 --height 200");
    ASSERT_EQ(r.code, 0) << r.err;
    cv::Mat img = cv::imread((work() / "two.png").string());
    const cv::Vec3b left = img.at<cv::Vec3b>(100, 30), right = img.at<cv::Vec3b>(100, 170);
    EXPECT_GT(left[1], 100);  // green
    EXPECT_LT(left[2], 60);
    EXPECT_GT(right[2], 100);  // magenta
    EXPECT_LT(right[1], 60);

    // Points: a sphere of points (.xyz, no colours, no normals), splatted.
    r = run("$BIN/rgbd-render pts.xyz -o pts.png --width 200 --height 200 --metrics pts.json");
    ASSERT_EQ(r.code, 0) << r.err;
    img = cv::imread((work() / "pts.png").string());
    const auto m = nlohmann::json::parse(slurp(work() / "pts.json"));
    EXPECT_EQ(m["render"]["kind"], "points");
    // A sphere seen from anywhere: a disc filling 90% of the height (margins 5%: the point
    // centres span 180 px), without holes, grown by at most the splat radius (about 4 px for
    // a spacing of about 11 mm).
    const double covered_px = m["render"]["covered_pixels"].get<double>();
    EXPECT_GT(covered_px, 0.99 * M_PI * 90 * 90);
    EXPECT_LT(covered_px, M_PI * 96 * 96);

    // Heat map of the distance of the bumpy ellipsoid to the plain one: a colour bar on the
    // right, values from 0 up to about the bump (5% of 0.3 m = 15 mm).
    r =
        run("$BIN/rgbd-render bumpy.off --scalar distance --reference ell.off -o heat.png "
            "--width 300 --height 200 --metrics heat.json");
    ASSERT_EQ(r.code, 0) << r.err;
    img = cv::imread((work() / "heat.png").string());
    EXPECT_GT(img.cols, 300);
    EXPECT_EQ(img.rows, 200);
    const auto h = nlohmann::json::parse(slurp(work() / "heat.json"))["render"];
    ASSERT_TRUE(h.contains("color_bar")) << h.dump();
    EXPECT_GE(h["color_bar"]["x"].get<int>(), 300);
    EXPECT_EQ(h["scalar_min"].get<double>(), 0.0);
    EXPECT_GT(h["scalar_max"].get<double>(), 0.008);
    EXPECT_LT(h["scalar_max"].get<double>(), 0.016);
    // The model shows more than one colour of the map (the bumps vary).
    std::set<int> hues;
    for (int row = 0; row < 200; row += 4)
        for (int col = 0; col < 300; col += 4) {
            const cv::Vec3b p = img.at<cv::Vec3b>(row, col);
            if (!background(p)) hues.insert(p[0] / 32 * 64 + p[1] / 32 * 8 + p[2] / 32);
        }
    EXPECT_GT(hues.size(), 5u);
    // --scalar-max in mm.
    r =
        run("$BIN/rgbd-render bumpy.off --scalar distance --reference ell.off -o heat2.png "
            "--scalar-max 50 --metrics heat2.json -q");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NEAR(
        nlohmann::json::parse(slurp(work() / "heat2.json"))["render"]["scalar_max"].get<double>(),
        0.05, 1e-12);
}

TEST(RgbdRender, BadInputGivesOneLineAndNoPicture) {
    {
        std::ofstream(work() / "garbage.off") << "this is not a mesh\n";
        std::ofstream(work() / "nan.off") << "OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n";
        std::ofstream(work() / "truncated.off") << "OFF\n3 1 0\n0 0 0\n1 0 0\n";
        std::ofstream(work() / "empty.xyz") << "";
    }
    struct Case {
        std::string args;
        int code;
    };
    for (const Case& c : std::vector<Case>{
             {"missing.off -o bad.png", 1},
             {"garbage.off -o bad.png", 1},
             {"nan.off -o bad.png", 1},
             {"truncated.off -o bad.png", 1},
             {"empty.xyz -o bad.png", 1},
             {"ell.off -o bad.jpg", 2},
             {"ell.off", 2},
             {"ell.off -o bad.png --width 0", 2},
             {"ell.off -o bad.png --view diagonal", 2},
             {"ell.off -o bad.png --elevation 120", 2},
             {"ell.off -o bad.png --up 0,0,0", 2},
             {"ell.off -o bad.png --scalar distance", 2},
             {"ell.off -o bad.png --scalar confidence", 2},
             {"pts.xyz -o bad.png --scalar confidence", 1},
             {"ell.off -o bad.png --point-size -1", 2},
         }) {
        SCOPED_TRACE(c.args);
        const Outcome r = run("$BIN/rgbd-render " + c.args);
        EXPECT_EQ(r.code, c.code) << r.err;
        EXPECT_EQ(line_count(r.err), c.code == 2 ? 2 : 1) << r.err;  // usage: + --help hint
        EXPECT_NE(r.err.find("rgbd-render"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(work() / "bad.png"));
        EXPECT_FALSE(fs::exists(work() / "bad.jpg"));
    }
    // The failing file is named.
    const Outcome r = run("$BIN/rgbd-render nan.off -o bad.png");
    EXPECT_NE(r.err.find("nan.off"), std::string::npos) << r.err;
}
