// Contract of the rgbd-synth tool: help, usage errors, runtime errors, refusal of a
// non-empty output folder, and a small complete capture.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace {

namespace fs = std::filesystem;

struct ToolRun {
    int code = -1;
    std::string out, err;
};

std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

class RgbdSynthTool : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("rgbd_synth_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    ToolRun run(const std::string& args) {
        const fs::path exe = fs::path(RGBD_BINARY_DIR) / "rgbd-synth";
        const std::string cmd = "'" + exe.string() + "' " + args + " >'" +
                                (dir_ / "out.txt").string() + "' 2>'" +
                                (dir_ / "err.txt").string() + "'";
        const int status = std::system(cmd.c_str());
        ToolRun r;
        r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        r.out = slurp(dir_ / "out.txt");
        r.err = slurp(dir_ / "err.txt");
        return r;
    }

    fs::path dir_;
};

TEST_F(RgbdSynthTool, HelpGoesToStdoutWithDefaults) {
    const ToolRun r = run("--help");
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find("Usage: rgbd-synth MESH -o CAPTURE_DIR"), std::string::npos);
    for (const char* opt :
         {"--rig", "--sensors", "--height-m", "--up", "--noise", "--calib-error-deg",
          "--calib-error-mm", "--frames", "--seed", "Example"})
        EXPECT_NE(r.out.find(opt), std::string::npos) << opt;
    EXPECT_NE(r.out.find("(=0.45)"), std::string::npos);
    EXPECT_TRUE(r.err.empty());
    EXPECT_EQ(run("--version").code, 0);
}

TEST_F(RgbdSynthTool, UsageErrorsExitTwoWithOneLine) {
    for (const std::string args :
         {"--no-such-option", "mesh.off", "mesh.off -o x --rig dome", "mesh.off -o x --noise loud",
          "mesh.off -o x --sensors 0", "mesh.off -o x --sensors abc"}) {
        const ToolRun r = run(args);
        EXPECT_EQ(r.code, 2) << args;
        EXPECT_EQ(r.err.rfind("rgbd-synth: error: ", 0), 0u) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_TRUE(r.out.empty());
    }
}

TEST_F(RgbdSynthTool, BadSceneValuesAreUsageErrorsNamingTheOption) {
    for (const auto& [args, option] : std::vector<std::pair<std::string, std::string>>{
             {"mesh.off -o x --walls 7", "--walls"},
             {"mesh.off -o x --plinth-height-m -1", "--plinth-height-m"},
             {"mesh.off -o x --plinth-height-m nan", "--plinth-height-m"},
             {"mesh.off -o x --clutter=-2", "--clutter"},
             {"mesh.off -o x --people 99", "--people"},
             {"mesh.off -o x --scene garden", "garden"},
             {"mesh.off -o x --rig turntable --scene room", "--rig ring"},
             {"mesh.off -o x --floor --motion turn", "--motion none"}}) {
        const ToolRun r = run(args);
        EXPECT_EQ(r.code, 2) << args;
        EXPECT_EQ(r.err.rfind("rgbd-synth: error: ", 0), 0u) << r.err;
        EXPECT_NE(r.err.find(option), std::string::npos) << args << ": " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
}

TEST_F(RgbdSynthTool, MissingMeshIsARuntimeErrorNamingTheFile) {
    const ToolRun r =
        run("'" + (dir_ / "nope.off").string() + "' -o '" + (dir_ / "cap").string() + "'");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("nope.off"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir_ / "cap"));
}

TEST_F(RgbdSynthTool, RefusesANonEmptyOutputFolder) {
    fs::create_directories(dir_ / "cap");
    std::ofstream(dir_ / "cap" / "keep.txt") << "x";
    const ToolRun r =
        run("'" + (dir_ / "nope.off").string() + "' -o '" + (dir_ / "cap").string() + "'");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("not empty"), std::string::npos) << r.err;
    EXPECT_TRUE(fs::exists(dir_ / "cap" / "keep.txt"));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "cap"), fs::directory_iterator{}), 1);
}

TEST_F(RgbdSynthTool, WritesACompleteCaptureWithGroundTruth) {
    // A small OFF mesh written here: an octahedron.
    const fs::path mesh = dir_ / "octa.off";
    std::ofstream(mesh) << "OFF\n6 8 0\n1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0 1\n0 0 -1\n"
                           "3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n"
                           "3 0 3 5\n";
    const fs::path cap = dir_ / "cap";
    const ToolRun r =
        run("'" + mesh.string() + "' -o '" + cap.string() + "' --sensors 3 --frames 2");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(r.out.empty());
    EXPECT_NE(r.err.find("3 sensors"), std::string::npos) << r.err;
    for (const char* f :
         {"rig.json", "framesets.csv", "k2-0/frames.csv", "k2-2/frames.csv",
          "gt/world_from_depth.json", "gt/mesh.ply", "gt/clock.json", "gt/scene.json",
          "gt/k2-1/depth_clean/000001.png", "gt/k2-1/labels/000001.png"})
        EXPECT_TRUE(fs::exists(cap / f)) << f;
    const auto poses = nlohmann::json::parse(slurp(cap / "gt/world_from_depth.json"));
    EXPECT_EQ(poses.size(), 3u);
    EXPECT_EQ(poses["k2-0"].size(), 4u);
    const auto scene = nlohmann::json::parse(slurp(cap / "gt/scene.json"));
    EXPECT_EQ(scene["seed"], 1);
    EXPECT_TRUE(scene.contains("texture"));
    // No temporary folder is left beside the capture.
    for (const auto& e : fs::directory_iterator(dir_))
        EXPECT_EQ(e.path().filename().string().find(".cap.partial"), std::string::npos);
    // Refuses to overwrite it.
    EXPECT_EQ(run("'" + mesh.string() + "' -o '" + cap.string() + "'").code, 1);
}

}  // namespace
