// rgbd-texture's command-line contract (issue 36, as tests/cli/failure_contract_test.cpp for the
// other tools): on the 6-Kinect ring of a bumpy ellipsoid (render_bumpy_ring) the true mesh is
// textured into a .glb; every bad input - a mesh no camera sees, a capture with a colour image
// removed, a colour image of the wrong size, an output that cannot be written, a .ply output -
// exits 1 (runtime) or 2 (usage; plus the --help hint) with one error line naming the file,
// and leaves no model file (.obj, .mtl, .png, .glb) and no temporary file behind. And
// rgbd-reconstruct -o model.glb shows the textured model in its report; rgbd-render draws it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>
#include <set>
#include <string>

#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_texture_cli_test")

/// The first colour image of the capture's first sensor folder (frames.csv's first row).
fs::path first_colour_image(const fs::path& capture) {
    for (const auto& e : fs::directory_iterator(capture)) {
        if (!fs::exists(e.path() / "frames.csv")) continue;
        std::ifstream csv(e.path() / "frames.csv");
        std::string header, row;
        std::getline(csv, header);
        std::getline(csv, row);
        // index,time_ns,depth,color[,...]
        std::size_t at = 0;
        for (int k = 0; k < 3; ++k) at = row.find(',', at) + 1;
        const std::string colour = row.substr(at, row.find(',', at) - at);
        return e.path() / colour;
    }
    return {};
}

std::set<std::string> entries() {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(temp_root()))
        names.insert(e.path().filename().string());
    return names;
}

struct Case {
    std::string command;  ///< after "$BIN/rgbd-texture "
    std::string names;    ///< the error line must contain this (the file)
    int code;             ///< 1 = runtime error, 2 = usage error
};

}  // namespace

TEST(RgbdTextureCli, TexturesTheRingAndFailsCleanlyOnBadInput) {
    rgbd::test::render_bumpy_ring(temp_root());
    const fs::path root = temp_root();
    ASSERT_TRUE(fs::exists(root / "cap" / "gt" / "mesh.ply"));

    // The good case first: the bad cases below differ from it in one thing each.
    Outcome r =
        run("$BIN/rgbd-texture cap/gt/mesh.ply --capture cap -o good.glb --metrics good.json");
    ASSERT_EQ(r.code, 0) << r.err;
    ASSERT_TRUE(fs::exists(root / "good.glb"));
    const auto metrics = read_json(root / "good.json");
    EXPECT_GT(metrics["texture"]["atlas"]["charts"].get<int>(), 0);
    EXPECT_LT(metrics["texture"]["selection"]["unseen_faces"].get<double>(),
              0.5 * metrics["texture"]["faces"].get<double>())
        << metrics["texture"].dump();
    fs::remove(root / "good.glb");
    fs::remove(root / "good.json");

    // A mesh no camera sees: one triangle 100 m away.
    std::ofstream(root / "far.off") << "OFF\n3 1 0\n100 100 100\n100.1 100 100\n100 100.1 100\n"
                                       "3 0 1 2\n";
    // A capture with its first colour image removed, and one with it the wrong size.
    const fs::path image = first_colour_image(root / "cap");
    ASSERT_FALSE(image.empty());
    const fs::path relative = fs::relative(image, root / "cap");
    for (const char* copy : {"cap_missing", "cap_small"}) {
        fs::remove_all(root / copy);
        fs::copy(root / "cap", root / copy, fs::copy_options::recursive);
    }
    fs::remove(root / "cap_missing" / relative);
    const cv::Mat full = cv::imread(image.string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(full.empty());
    fs::remove(root / "cap_small" / relative);
    cv::imwrite((root / "cap_small" / relative).string(),
                cv::Mat(full.rows / 2, full.cols / 2, CV_8UC3, cv::Scalar(90, 90, 90)));
    fs::create_directories(root / "a_folder.glb");  // an output path that is a folder

    const std::string missing = (fs::path("cap_missing") / relative).string();
    const std::string small = (fs::path("cap_small") / relative).string();
    const Case cases[] = {
        {"far.off --capture cap -o out.obj", "far.off", 1},
        {"cap/gt/mesh.ply --capture cap_missing -o out.obj", missing, 1},
        {"cap/gt/mesh.ply --capture cap_missing -o out.glb", missing, 1},
        {"cap/gt/mesh.ply --capture cap_small -o out.obj", small, 1},
        {"cap/gt/mesh.ply --capture cap -o no-such-folder/out.obj", "no-such-folder/out", 1},
        {"cap/gt/mesh.ply --capture cap -o no-such-folder/out.glb", "no-such-folder/out.glb", 1},
        {"cap/gt/mesh.ply --capture cap -o a_folder.glb", "a_folder.glb", 1},
        {"cap/gt/mesh.ply --capture cap -o out.ply", "out.ply", 2},
        {"no-such-mesh.ply --capture cap -o out.obj", "no-such-mesh.ply", 1},
    };
    const std::set<std::string> before = entries();
    const std::regex captured("(out|err)[0-9]+\\.txt");
    for (const Case& c : cases) {
        SCOPED_TRACE(c.command);
        // -q: no progress lines (a loaded machine takes over a second to find no face seen).
        r = run("$BIN/rgbd-texture -q " + c.command);
        EXPECT_EQ(r.code, c.code) << r.err;
        // One error line; a usage error adds the hint "Try 'rgbd-texture --help' ...".
        EXPECT_EQ(line_count(r.err), c.code == 2 ? 2 : 1) << r.err;
        if (c.code == 2) EXPECT_NE(r.err.find("--help"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find(c.names), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("error"), std::string::npos) << r.err;
        EXPECT_TRUE(r.out.empty()) << r.out.substr(0, 200);
        for (const std::string& name : entries()) {
            if (before.count(name) || std::regex_match(name, captured)) continue;
            ADD_FAILURE() << "left behind: " << name;
            fs::remove_all(root / name);
        }
        // Nothing inside the folder output either.
        EXPECT_TRUE(fs::is_empty(root / "a_folder.glb"));
    }
}

// rgbd-reconstruct -o model.glb: the report shows the textured model beside the vertex-coloured
// one (same camera), the page names them and the viewer command; rgbd-render draws the .glb with
// its texture.
TEST(RgbdTextureCli, ReconstructReportShowsTheTexturedModel) {
    rgbd::test::render_bumpy_ring(temp_root());
    const fs::path root = temp_root();
    Outcome r = run("$BIN/rgbd-reconstruct cap -o model.glb --report rep -q");
    ASSERT_EQ(r.code, 0) << r.err;
    ASSERT_TRUE(fs::exists(root / "model.glb"));
    for (const char* picture : {"result.png", "textured.png", "textured_closeup.png"})
        EXPECT_TRUE(fs::exists(root / "rep" / picture)) << picture;
    const std::string page = slurp(root / "rep" / "index.html");
    EXPECT_NE(page.find("src=\"textured.png\""), std::string::npos);
    EXPECT_NE(page.find("rgbd-view model.glb"), std::string::npos);
    // Same camera, same object: the two pictures cover the same pixels but differ in colour.
    const cv::Mat plain = cv::imread((root / "rep" / "result.png").string(), cv::IMREAD_COLOR);
    const cv::Mat textured = cv::imread((root / "rep" / "textured.png").string(), cv::IMREAD_COLOR);
    ASSERT_EQ(plain.size(), textured.size());
    cv::Mat plain_bg, textured_bg;
    cv::inRange(plain, cv::Scalar(255, 255, 255), cv::Scalar(255, 255, 255), plain_bg);
    cv::inRange(textured, cv::Scalar(255, 255, 255), cv::Scalar(255, 255, 255), textured_bg);
    const int covered = static_cast<int>(plain.total()) - cv::countNonZero(plain_bg);
    EXPECT_GT(covered, 20000);
    EXPECT_NEAR(static_cast<int>(textured.total()) - cv::countNonZero(textured_bg), covered,
                0.01 * covered);
    EXPECT_GT(cv::norm(plain, textured, cv::NORM_L1) / covered, 3.0)
        << "the texture changes nothing";

    r = run("$BIN/rgbd-render model.glb -o model.png --metrics render.json -q");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(read_json(root / "render.json")["render"]["textured"].get<bool>());
}

// --refine-colour (issue 36 item 3) is accepted and reported: per camera the correction and the
// residuals, the residual not higher after; its iteration count is checked and applies only
// with it; rgbd-reconstruct takes it only for a textured model.
TEST(RgbdTextureCli, RefineColourIsAcceptedAndReported) {
    rgbd::test::render_bumpy_ring(temp_root());
    const fs::path root = temp_root();
    Outcome r =
        run("$BIN/rgbd-texture -q cap/gt/mesh.ply --capture cap -o refined.obj --refine-colour "
            "--refine-colour-iterations 20 --metrics refined.json");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto metrics = read_json(root / "refined.json");
    ASSERT_TRUE(metrics["texture"].contains("refine")) << metrics["texture"].dump();
    const auto& refine = metrics["texture"]["refine"];
    EXPECT_EQ(refine["cameras"].size(), metrics["texture"]["views"].get<std::size_t>());
    for (const auto& c : refine["cameras"]) {
        EXPECT_TRUE(c.contains("rotation_deg") && c.contains("translation_mm")) << c.dump();
        EXPECT_EQ(c["world_from_camera"].size(), 12u);
    }
    for (const auto& n : refine["iterations"]) EXPECT_LE(n.get<int>(), 20);
    EXPECT_LE(refine["residual_after"].get<double>(), refine["residual_before"].get<double>());
    for (const char* bad :
         {"--refine-colour --refine-colour-iterations 0", "--refine-colour-iterations 5"}) {
        r = run(std::string("$BIN/rgbd-texture -q cap/gt/mesh.ply --capture cap -o bad.obj ") +
                bad);
        EXPECT_EQ(r.code, 2) << bad << ": " << r.err;
        EXPECT_NE(r.err.find("refine-colour"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(root / "bad.obj"));
    }
    r = run("$BIN/rgbd-reconstruct -q cap -o plain.ply --refine-colour");
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("--refine-colour"), std::string::npos) << r.err;
}
