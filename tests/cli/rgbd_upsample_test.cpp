// Contract tests of rgbd-upsample (cli/README.md): help, exit codes, the capture folder found
// from rgbd:view.source or --capture, a missing colour image or one of another size than
// rig.json says (one-line error naming the file or the sizes, no partial output), a view
// without grid, and the point count on a rendered capture.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_upsample_test")

/// A 2-sensor capture of a sphere (OFF), rendered once, and its cleaned view stream.
class Upsample : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (fs::exists(temp_root() / "views.ply")) return;
        rgbd::test::write_ellipsoid_off(temp_root() / "ball.off", 40, 20, 0.2, 0.2, 0.2);
        Outcome r = run("$BIN/rgbd-synth ball.off -o cap --sensors 2 --height-m 0.4 -q");
        ASSERT_EQ(r.code, 0) << r.err;
        r = run("$BIN/rgbd-cloud cap -o views.ply");
        ASSERT_EQ(r.code, 0) << r.err;
    }
};

}  // namespace

TEST_F(Upsample, HelpDocumentsOptionsAndCaptureLookup) {
    const Outcome help = run("$BIN/rgbd-upsample --help");
    EXPECT_EQ(help.code, 0);
    for (const char* word : {"--neighbors", "--midpoints", "--capture", "view.source", "Example"})
        EXPECT_NE(help.out.find(word), std::string::npos) << word;
    EXPECT_TRUE(help.err.empty());
    EXPECT_EQ(run("$BIN/rgbd-upsample --version").code, 0);
}

TEST_F(Upsample, UsageErrorsExitTwo) {
    for (const char* args : {"--neighbors 5", "--sigma-color -1", "--no-such-option"}) {
        SCOPED_TRACE(args);
        const Outcome r = run(std::string("$BIN/rgbd-upsample views.ply -o never.ply ") + args);
        rgbd::test::expect_failure(r, 2, "rgbd-upsample", temp_root());
    }
}

TEST_F(Upsample, AddsPointsFromSourceOrCapture) {
    for (const char* args : {"", "--capture cap", "--neighbors 4", "--midpoints"}) {
        SCOPED_TRACE(args);
        const Outcome r =
            run(std::string("$BIN/rgbd-upsample views.ply -o up.ply --metrics m.json ") + args);
        ASSERT_EQ(r.code, 0) << r.err;
        EXPECT_GT(fs::file_size(temp_root() / "up.ply"),
                  2 * fs::file_size(temp_root() / "views.ply"));
        EXPECT_NE(slurp(temp_root() / "m.json").find("\"added\""), std::string::npos);
        const Outcome info = run("$BIN/rgbd-info up.ply");
        EXPECT_EQ(info.code, 0) << info.err;
        EXPECT_NE(info.out.find("synthetic"), std::string::npos) << info.out;
    }
}

namespace {

/// Copies the rendered capture to `name` and returns one of its colour images (empty if none).
fs::path copy_capture_and_pick_colour_image(const std::string& name) {
    fs::remove_all(temp_root() / name);
    fs::copy(temp_root() / "cap", temp_root() / name, fs::copy_options::recursive);
    fs::path victim;
    for (const auto& e : fs::recursive_directory_iterator(temp_root() / name))
        if (e.path().parent_path().filename() == "color") victim = e.path();
    return victim;
}

}  // namespace

TEST_F(Upsample, MissingColourImageIsAOneLineErrorAndNoOutput) {
    const fs::path victim = copy_capture_and_pick_colour_image("cap2");
    ASSERT_FALSE(victim.empty());
    fs::remove(victim);
    const Outcome r = run("$BIN/rgbd-upsample views.ply --capture cap2 -o never.ply");
    rgbd::test::expect_failure(r, 1, "rgbd-upsample", temp_root());
    EXPECT_NE(r.err.find(victim.filename().string()), std::string::npos) << r.err;
    const Outcome nocap = run("$BIN/rgbd-upsample views.ply --capture no-such-dir -o never.ply");
    EXPECT_EQ(nocap.code, 1);
    EXPECT_NE(nocap.err.find("no-such-dir"), std::string::npos) << nocap.err;
}

TEST_F(Upsample, ColourImageOfAnotherSizeThanTheRigIsAOneLineError) {
    const fs::path victim = copy_capture_and_pick_colour_image("cap3");
    ASSERT_FALSE(victim.empty());
    const cv::Mat image = cv::imread(victim.string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty());
    cv::Mat half(image.rows / 2, image.cols / 2, CV_8UC3, cv::Scalar(40, 80, 120));
    ASSERT_TRUE(cv::imwrite(victim.string(), half));
    const Outcome r = run("$BIN/rgbd-upsample views.ply --capture cap3 -o never.ply");
    rgbd::test::expect_failure(r, 1, "rgbd-upsample", temp_root());
    const std::string size = std::to_string(half.cols) + "x" + std::to_string(half.rows);
    EXPECT_TRUE(r.err.find(size) != std::string::npos ||
                r.err.find(victim.filename().string()) != std::string::npos)
        << r.err;
}

TEST_F(Upsample, ViewWithoutGridIsAnError) {
    std::ofstream(temp_root() / "flat.ply")
        << "ply\nformat ascii 1.0\nelement vertex 3\n"
           "property float x\nproperty float y\nproperty float z\n"
           "end_header\n0 0 1\n1 0 1\n0 1 1\n";
    const Outcome r = run("$BIN/rgbd-upsample flat.ply -o never.ply");
    rgbd::test::expect_failure(r, 1, "rgbd-upsample", temp_root());
    EXPECT_NE(r.err.find("grid"), std::string::npos) << r.err;
}
