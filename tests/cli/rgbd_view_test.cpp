// rgbd-view (issue 20 item 4): the page, three.js from libjs-three and the frames over HTTP; a
// corrupt frame file is answered 404 and marked in the index; in headless Chromium the page
// draws the cloud (a screenshot shows its colour) and the frame counter advances. A textured
// model (.glb; an .obj converted in memory) is served with three.js's GLTFLoader and drawn
// with its texture (issue 36). Skips the browser part when chromium or libjs-three is missing,
// saying so.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/textured_mesh_io.hpp"
#include "io/video.hpp"
#include "tests/support/capture_harness.hpp"

namespace {

using namespace rgbd::test::capture;
namespace fs = std::filesystem;
using rgbd::test::Outcome;
using rgbd::test::slurp;

/// A 12-frame video of a red ball moving along x, 2000 + 100 k points in frame k.
void write_ball_video(const fs::path& dir) {
    fs::remove_all(dir);
    rgbd::io::Rig rig;
    rig.sensors.resize(1);
    rig.sensors[0].id = "k2-0";
    rig.sensors[0].depth = {512, 424, 365.5, 365.5, 256, 212};
    rig.sensors[0].color = {512, 424, 365.5, 365.5, 256, 212};
    rgbd::io::VideoWriter writer(dir, rig, 30.0, {}, {{"placement", "nodes"}});
    for (int k = 0; k < 12; ++k) {
        rgbd::io::ColoredPoints p;
        const int n = 2000 + 100 * k;
        for (int i = 0; i < n; ++i) {
            // Fibonacci sphere of radius 0.2 m.
            const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1 - z * z);
            const double a = i * 2.399963229728653;
            p.xyz.emplace_back(0.02f * k + 0.2f * r * std::cos(a), 0.2f * r * std::sin(a),
                               1.0f + 0.2f * z);
            p.rgb.push_back(rgbd::Rgb{230, 30, 30});
        }
        rgbd::io::VideoFrame info;
        info.set = k;
        info.time_ns = k * 33'333'333;
        info.sensors = 1;
        writer.add(p, info);
        writer.update_last(1.0, 10.0);
    }
    writer.finish({{"sets_fused", 12}}, "test");
}

std::string curl(int port, const std::string& path, const std::string& extra = "") {
    return run("curl -s --max-time 20 " + extra + " http://127.0.0.1:" + std::to_string(port) +
               path)
        .out;
}

TEST(RgbdView, ServesThePageThreeJsAndFramesAndSkipsACorruptOne) {
    if (!fs::exists("/usr/share/javascript/three/build/three.min.js"))
        GTEST_SKIP() << "libjs-three is not installed";
    if (std::system("command -v curl >/dev/null 2>&1") != 0) GTEST_SKIP() << "no curl";
    const fs::path dir = temp_root();
    write_ball_video(dir / "ball");
    // Frame 5 is corrupted on disk.
    { std::ofstream(dir / "ball" / rgbd::io::video_frame_file(5), std::ios::trunc) << "broken"; }
    const int port = free_port();
    start(dir, "view",
          "$BIN/rgbd-view ball --port " + std::to_string(port) +
              " --duration-s 120 --metrics view.json");
    std::string page;
    for (int i = 0; i < 200 && page.find("three.min.js") == std::string::npos; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        page = curl(port, "/");
    }
    ASSERT_NE(page.find("three.min.js"), std::string::npos) << slurp(dir / "view.err");
    EXPECT_GT(curl(port, "/three.min.js").size(), 100000u);
    EXPECT_NE(curl(port, "/OrbitControls.js").find("OrbitControls"), std::string::npos);
    const json info = json::parse(curl(port, "/api/info"));
    EXPECT_EQ(info["mode"], "video");
    ASSERT_EQ(info["frames"].size(), 12u);
    EXPECT_FALSE(info["frames"][5]["ok"].get<bool>());
    EXPECT_TRUE(info["frames"][4]["ok"].get<bool>());
    const std::string frame3 = curl(port, "/api/frame/3");
    ASSERT_EQ(frame3.size(), 16u + 15u * 2300u);
    EXPECT_EQ(frame3.substr(0, 8), "RGBDPTS1");
    EXPECT_NE(curl(port, "/api/frame/5", "-o /dev/null -w \"%{http_code}\"").find("404"),
              std::string::npos);
    EXPECT_NE(curl(port, "/api/frame/99", "-o /dev/null -w \"%{http_code}\"").find("404"),
              std::string::npos);

    // The page in a browser: the cloud is drawn (red pixels) and the frame counter advances.
    if (std::system("command -v chromium >/dev/null 2>&1") != 0) {
        ::kill(pid_of(dir, "view"), SIGTERM);
        GTEST_SKIP() << "chromium is not installed: the browser check is skipped";
    }
    const std::string chromium =
        "chromium --headless --no-sandbox --disable-gpu --enable-unsafe-swiftshader "
        "--use-angle=swiftshader --disable-quic --no-first-run --disable-background-networking "
        "--disable-component-update --disable-sync --user-data-dir=$(mktemp -d) "
        "--window-size=640,480 ";
    const std::string url = " http://127.0.0.1:" + std::to_string(port) + "/";
    Outcome shot = run("timeout 120 " + chromium + "--virtual-time-budget=3000 --screenshot=" +
                       (dir / "view.png").string() + url + " 2>/dev/null");
    ASSERT_TRUE(fs::exists(dir / "view.png")) << shot.err;
    const cv::Mat png = cv::imread((dir / "view.png").string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(png.empty());
    cv::Mat red;
    cv::inRange(png, cv::Scalar(0, 0, 150), cv::Scalar(90, 90, 255), red);
    EXPECT_GT(cv::countNonZero(red), 500) << "no red cloud in the screenshot";
    // The page playing in real time: it asks for frame k + 1 only once it has drawn frame k,
    // so the frames the server hands out count the frame counter's steps. No time limit but
    // a generous one: only progress is checked.
    start(dir, "browser", "exec timeout 300 " + chromium + url);
    const auto served = [&] {
        const std::string stats = curl(port, "/api/stats");
        return stats.empty() ? -1 : json::parse(stats)["frames_served"].get<int>();
    };
    const int before = served();
    int after = before;
    for (int i = 0; i < 1200 && after < before + 6; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        after = served();
    }
    EXPECT_GE(after, before + 6) << "the page did not step through the frames";
    const json stats = json::parse(curl(port, "/api/stats"));
    EXPECT_NE(stats["last_frame"], 5) << "the corrupt frame is never drawn";
    ::kill(pid_of(dir, "browser"), SIGTERM);
    wait_for(dir, "browser", 30);
    ::kill(pid_of(dir, "view"), SIGTERM);
    EXPECT_EQ(wait_for(dir, "view", 30), 0) << slurp(dir / "view.err");
}

/// A 0.4 m square in the z = 0 plane facing +z, textured left half red, right half green (no
/// vertex colours: only the texture can colour it).
rgbd::TexturedMesh red_green_square() {
    rgbd::TexturedMesh m;
    m.vertices = {{-0.2, -0.2, 0}, {0.2, -0.2, 0}, {0.2, 0.2, 0}, {-0.2, 0.2, 0}};
    m.faces = {{{0, 1, 2}}, {{0, 2, 3}}};
    // glTF convention: v down, so vertex 3 (top-left) is (0, 0).
    m.uvs = {{0.f, 1.f}, {1.f, 1.f}, {1.f, 0.f}, {0.f, 0.f}};
    m.face_uvs = m.faces;
    m.face_atlas = {0, 0};
    cv::Mat atlas(64, 64, CV_8UC3, cv::Scalar(30, 30, 230));        // BGR red
    atlas(cv::Rect(32, 0, 32, 64)).setTo(cv::Scalar(30, 200, 30));  // green
    m.atlases = {atlas};
    return m;
}

const std::string kChromium =
    "chromium --headless --no-sandbox --disable-gpu --enable-unsafe-swiftshader "
    "--use-angle=swiftshader --disable-quic --no-first-run --disable-background-networking "
    "--disable-component-update --disable-sync --user-data-dir=$(mktemp -d) "
    "--window-size=640,480 ";

TEST(RgbdView, ShowsATexturedModel) {
    if (!fs::exists("/usr/share/javascript/three/examples/js/loaders/GLTFLoader.js"))
        GTEST_SKIP() << "libjs-three (with its GLTFLoader) is not installed";
    if (std::system("command -v curl >/dev/null 2>&1") != 0) GTEST_SKIP() << "no curl";
    const fs::path dir = temp_root();
    const rgbd::TexturedMesh square = red_green_square();
    rgbd::io::write_textured_mesh(dir / "square.glb", square);
    rgbd::io::write_textured_mesh(dir / "square.obj", square);
    for (const char* file : {"square.glb", "square.obj"}) {
        SCOPED_TRACE(file);
        const int port = free_port();
        start(dir, "model",
              "$BIN/rgbd-view " + std::string(file) + " --port " + std::to_string(port) +
                  " --duration-s 120 --up y");
        std::string page;
        for (int i = 0; i < 200 && page.find("GLTFLoader.js") == std::string::npos; ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
            page = curl(port, "/");
        }
        ASSERT_NE(page.find("GLTFLoader.js"), std::string::npos) << slurp(dir / "model.err");
        EXPECT_NE(curl(port, "/GLTFLoader.js").find("GLTFLoader"), std::string::npos);
        const json info = json::parse(curl(port, "/api/info"));
        EXPECT_EQ(info["mode"], "model");
        EXPECT_EQ(info["triangles"], 2);
        EXPECT_TRUE(info["textured"].get<bool>());
        const std::string glb = curl(port, "/model.glb");
        ASSERT_GT(glb.size(), 20u);
        EXPECT_EQ(glb.substr(0, 4), "glTF");
        if (std::string(file) == "square.glb") {
            EXPECT_EQ(glb, slurp(dir / "square.glb"));
        }

        if (std::system("command -v chromium >/dev/null 2>&1") != 0) {
            ::kill(pid_of(dir, "model"), SIGTERM);
            wait_for(dir, "model", 30);
            GTEST_SKIP() << "chromium is not installed: the browser check is skipped";
        }
        const fs::path png_path = dir / (std::string(file) + ".png");
        Outcome shot = run("timeout 120 " + kChromium +
                           "--virtual-time-budget=5000 --screenshot=" + png_path.string() +
                           " http://127.0.0.1:" + std::to_string(port) + "/ 2>/dev/null");
        ASSERT_TRUE(fs::exists(png_path)) << shot.err;
        const cv::Mat png = cv::imread(png_path.string(), cv::IMREAD_COLOR);
        ASSERT_FALSE(png.empty());
        // The centre is the model, not the background (#202428).
        const cv::Vec3b centre = png.at<cv::Vec3b>(png.rows / 2, png.cols / 2);
        EXPECT_GT(
            std::abs(centre[0] - 0x28) + std::abs(centre[1] - 0x24) + std::abs(centre[2] - 0x20),
            60)
            << "the centre pixel is the background";
        // Both halves of the texture are drawn, red on the left, green on the right.
        cv::Mat red, green;
        cv::inRange(png, cv::Scalar(0, 0, 140), cv::Scalar(80, 80, 255), red);
        cv::inRange(png, cv::Scalar(0, 120, 0), cv::Scalar(80, 255, 80), green);
        EXPECT_GT(cv::countNonZero(red), 3000) << "no red half in the screenshot";
        EXPECT_GT(cv::countNonZero(green), 3000) << "no green half in the screenshot";
        if (cv::countNonZero(red) > 0 && cv::countNonZero(green) > 0) {
            cv::Moments mr = cv::moments(red, true), mg = cv::moments(green, true);
            EXPECT_LT(mr.m10 / mr.m00, mg.m10 / mg.m00) << "red is left of green";
        }
        ::kill(pid_of(dir, "model"), SIGTERM);
        EXPECT_EQ(wait_for(dir, "model", 30), 0) << slurp(dir / "model.err");
    }
}

/// A 0.4 m square standing in the x = 0 plane of a z-up world, facing +x, textured top half
/// red (z > 0) and bottom half green, with up = +z (as the texture stage records a ring's up).
rgbd::TexturedMesh standing_square() {
    rgbd::TexturedMesh m;
    m.vertices = {{0, -0.2, -0.2}, {0, 0.2, -0.2}, {0, 0.2, 0.2}, {0, -0.2, 0.2}};
    m.faces = {{{0, 1, 2}}, {{0, 2, 3}}};
    m.uvs = {{0.f, 1.f}, {1.f, 1.f}, {1.f, 0.f}, {0.f, 0.f}};  // v down: z = +0.2 is v = 0
    m.face_uvs = m.faces;
    m.face_atlas = {0, 0};
    cv::Mat atlas(64, 64, CV_8UC3, cv::Scalar(30, 200, 30));       // BGR green
    atlas(cv::Rect(0, 0, 64, 32)).setTo(cv::Scalar(30, 30, 230));  // red top half
    m.atlases = {atlas};
    m.up = Eigen::Vector3d::UnitZ();
    return m;
}

// The .glb's root node turns its z up to glTF's +Y: three.js (a glTF viewer) shows the square
// upright, red above green, with rgbd-view's default --up (the file's) and with --up z (the
// model's coordinates, turned alike).
TEST(RgbdView, AGlbWithAnUpStandsUpright) {
    if (!fs::exists("/usr/share/javascript/three/examples/js/loaders/GLTFLoader.js"))
        GTEST_SKIP() << "libjs-three (with its GLTFLoader) is not installed";
    if (std::system("command -v curl >/dev/null 2>&1") != 0) GTEST_SKIP() << "no curl";
    if (std::system("command -v chromium >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "chromium is not installed: the browser check is skipped";
    const fs::path dir = temp_root();
    rgbd::io::write_textured_mesh(dir / "standing.glb", standing_square());
    for (const std::string up : {"", " --up z"}) {
        SCOPED_TRACE("rgbd-view standing.glb" + up);
        const int port = free_port();
        start(dir, "upright",
              "$BIN/rgbd-view standing.glb --port " + std::to_string(port) + " --duration-s 120" +
                  up);
        std::string page;
        for (int i = 0; i < 200 && page.find("GLTFLoader.js") == std::string::npos; ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
            page = curl(port, "/");
        }
        ASSERT_NE(page.find("GLTFLoader.js"), std::string::npos) << slurp(dir / "upright.err");
        const json info = json::parse(curl(port, "/api/info"));
        EXPECT_NEAR(info["up"][1].get<double>(), 1.0, 1e-9) << info.dump();
        const fs::path png_path = dir / "upright.png";
        fs::remove(png_path);
        Outcome shot = run("timeout 120 " + kChromium +
                           "--virtual-time-budget=5000 --screenshot=" + png_path.string() +
                           " http://127.0.0.1:" + std::to_string(port) + "/ 2>/dev/null");
        ::kill(pid_of(dir, "upright"), SIGTERM);
        EXPECT_EQ(wait_for(dir, "upright", 30), 0) << slurp(dir / "upright.err");
        ASSERT_TRUE(fs::exists(png_path)) << shot.err;
        const cv::Mat png = cv::imread(png_path.string(), cv::IMREAD_COLOR);
        ASSERT_FALSE(png.empty());
        cv::Mat red, green;
        cv::inRange(png, cv::Scalar(0, 0, 140), cv::Scalar(80, 80, 255), red);
        cv::inRange(png, cv::Scalar(0, 120, 0), cv::Scalar(80, 255, 80), green);
        ASSERT_GT(cv::countNonZero(red), 2000) << "no red half in the screenshot";
        ASSERT_GT(cv::countNonZero(green), 2000) << "no green half in the screenshot";
        const cv::Moments mr = cv::moments(red, true), mg = cv::moments(green, true);
        const double dy = mg.m01 / mg.m00 - mr.m01 / mr.m00;  // rows grow downwards
        const double dx = std::abs(mg.m10 / mg.m00 - mr.m10 / mr.m00);
        EXPECT_GT(dy, 40) << "red is not above green";
        EXPECT_GT(dy, 2 * dx) << "the square is not upright";
    }
}

TEST(RgbdView, UsageAndBadFolder) {
    Outcome r = run("$BIN/rgbd-view --help");
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find("Usage: "), std::string::npos);
    r = run("$BIN/rgbd-view");
    EXPECT_EQ(r.code, 2);
    fs::create_directories(temp_root() / "not_a_video");
    r = run("$BIN/rgbd-view not_a_video --port 0 --duration-s 1");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("video.json"), std::string::npos) << r.err;
    std::ofstream(temp_root() / "garbage.glb") << "not a glTF file";
    r = run("$BIN/rgbd-view garbage.glb --port 0 --duration-s 1");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("garbage.glb"), std::string::npos) << r.err;
    r = run("$BIN/rgbd-view garbage.glb --port 0 --duration-s 1 --up 0,0,0");
    EXPECT_EQ(r.code, 2) << r.err;
}

}  // namespace
