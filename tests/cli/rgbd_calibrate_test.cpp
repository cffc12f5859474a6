// Contract and accuracy tests of rgbd-calibrate (issue 19) on synthetic board captures with a
// known answer (rgbd-synth --target charuco: 4 and 6 Kinect v2 sensors, noise on, rig.json
// 10 deg / 100 mm off): every sensor within the issue's targets (0.3 deg, <= 2 mm RMS in a
// 0.3 m ball at the ring centre), other rig.json fields kept; bad input (no board, a sensor that
// never shares the board, a board file that does not match the print or is not JSON, a blurred
// board, absurd options) fails with a one-line error and no output. --refine on the Max Planck
// bust (../shared/data, skipped when absent), 6 sensors, 8 frame sets, 3 deg / 30 mm off ->
// within 0.2 deg and <= 1.5 mm RMS on the surface.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>

#include "io/mesh_io.hpp"
#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"
#include "toolkit/pose.hpp"

namespace fs = std::filesystem;
using rgbd::Pose;
using rgbd::test::Outcome;
using rgbd::test::slurp;

namespace {

fs::path temp_root() {
    static const fs::path root = rgbd::test::scratch_dir("rgbd_calibrate_test");
    return root;
}

Outcome run(const std::string& command) { return rgbd::test::run_in(temp_root(), command); }

Pose pose_of(const nlohmann::json& m) {
    Eigen::Matrix4d a;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) a(r, c) = m[r][c].get<double>();
    Pose p;
    p.matrix() = a;
    return p;
}

std::map<std::string, Pose> rig_poses(const fs::path& rig_json) {
    const auto j = nlohmann::json::parse(slurp(rig_json));
    std::map<std::string, Pose> out;
    for (const auto& s : j["sensors"]) out[s["id"]] = pose_of(s["world_from_depth"]);
    return out;
}

std::map<std::string, Pose> true_poses(const fs::path& capture) {
    const auto j = nlohmann::json::parse(slurp(capture / "gt" / "world_from_depth.json"));
    std::map<std::string, Pose> out;
    for (const auto& [id, m] : j.items()) out[id] = pose_of(m);
    return out;
}

struct Errors {
    double max_deg = 0;     ///< worst rotation error, relative to the anchor
    double max_rms_mm = 0;  ///< worst RMS displacement of the points
};

/// Errors of a rig against the truth, the anchor's pose taken as the gauge, over `points`.
Errors rig_errors(const std::map<std::string, Pose>& est, const std::map<std::string, Pose>& truth,
                  const std::string& anchor, const std::vector<Eigen::Vector3d>& points) {
    const Pose gauge = truth.at(anchor) * est.at(anchor).inverse();
    Errors e;
    for (const auto& [id, t] : truth) {
        const Pose moved = gauge * est.at(id) * t.inverse();
        double sum = 0;
        for (const auto& p : points) sum += (moved * p - p).squaredNorm();
        e.max_deg = std::max(e.max_deg, rgbd::rotation_error_deg(gauge * est.at(id), t));
        e.max_rms_mm = std::max(e.max_rms_mm, 1e3 * std::sqrt(sum / points.size()));
    }
    return e;
}

/// Points in a ball of `radius` around the capture's ring centre (gt/scene.json).
std::vector<Eigen::Vector3d> ball(const fs::path& capture, double radius) {
    const auto scene = nlohmann::json::parse(slurp(capture / "gt" / "scene.json"));
    const Eigen::Vector3d c(scene["ring_centre"][0], scene["ring_centre"][1],
                            scene["ring_centre"][2]);
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<Eigen::Vector3d> out;
    while (out.size() < 2000) {
        const Eigen::Vector3d p(u(rng), u(rng), u(rng));
        if (p.norm() <= 1) out.push_back(c + radius * p);
    }
    return out;
}

class Calibrate : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        for (const char* args : {"-o board4 --sensors 4 --frames 16 --seed 4",
                                 "-o board6 --sensors 6 --frames 18 --seed 6"}) {
            if (fs::exists(temp_root() / std::string(args).substr(3, 6))) continue;
            const Outcome r = run(std::string("$BIN/rgbd-synth --target charuco -q ") + args +
                                  " --calib-error-deg 10 --calib-error-mm 100");
            ASSERT_EQ(r.code, 0) << r.err;
        }
    }
};

}  // namespace

TEST_F(Calibrate, HelpAndUsageErrors) {
    const Outcome help = run("$BIN/rgbd-calibrate --help");
    EXPECT_EQ(help.code, 0);
    for (const char* word : {"--board", "--anchor", "--refine", "--frameset", "Example", "Exit"})
        EXPECT_NE(help.out.find(word), std::string::npos) << word;
    EXPECT_EQ(run("$BIN/rgbd-calibrate --version").code, 0);
    for (const char* args :
         {"board4", "board4 board6 -o never.json", "board4 -o never.json --anchor nosuch",
          "board4 -o never.json --min-corners 2", "board4 -o never.json --max-plane-mm -1",
          "board4 -o never.json --max-rms-px 0", "board4 --refine --board b.json -o never.json",
          "board4 -o never.json --no-such-option"}) {
        SCOPED_TRACE(args);
        const Outcome r = run(std::string("$BIN/rgbd-calibrate ") + args);
        rgbd::test::expect_failure(r, 2, "rgbd-calibrate", temp_root(), "never.json");
    }
}

TEST_F(Calibrate, RingOfFourAndSixWithinTargets) {
    for (const std::string cap : {"board4", "board6"}) {
        SCOPED_TRACE(cap);
        const Outcome r =
            run("$BIN/rgbd-calibrate " + cap + " -o " + cap + ".json --metrics " + cap + "_m.json");
        ASSERT_EQ(r.code, 0) << r.err;
        const auto truth = true_poses(temp_root() / cap);
        const auto before = rig_poses(temp_root() / cap / "rig.json");
        const auto after = rig_poses(temp_root() / (cap + ".json"));
        const auto points = ball(temp_root() / cap, 0.3);
        const Errors start = rig_errors(before, truth, "k2-0", points);
        const Errors end = rig_errors(after, truth, "k2-0", points);
        EXPECT_GT(start.max_deg, 9.9);  // the rig.json of the capture is 10 deg off
        EXPECT_LE(end.max_deg, 0.3);
        EXPECT_LE(end.max_rms_mm, 2.0);
        // The anchor keeps its pose; every sensor is in the table; other fields are kept.
        EXPECT_TRUE(after.at("k2-0").isApprox(before.at("k2-0"), 1e-12));
        for (const auto& [id, p] : truth) EXPECT_NE(r.out.find(id), std::string::npos) << id;
        auto a = nlohmann::json::parse(slurp(temp_root() / cap / "rig.json"));
        auto b = nlohmann::json::parse(slurp(temp_root() / (cap + ".json")));
        for (auto* j : {&a, &b})
            for (auto& s : (*j)["sensors"]) s.erase("world_from_depth");
        EXPECT_EQ(a, b);
        const auto m = nlohmann::json::parse(slurp(temp_root() / (cap + "_m.json")));
        EXPECT_LT(m["reprojection_rms_px"].get<double>(), 1.0);
        for (const auto& s : m["sensors"]) {
            EXPECT_GT(s["linked"].get<int>(), 0) << s;
            EXPECT_LT(std::abs(s["plane_median_mm"].get<double>()), 5.0) << s;
        }
    }
}

TEST_F(Calibrate, AnotherAnchorKeepsItsPose) {
    const Outcome r = run("$BIN/rgbd-calibrate board4 -o anchor2.json --anchor k2-2");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto before = rig_poses(temp_root() / "board4" / "rig.json");
    const auto after = rig_poses(temp_root() / "anchor2.json");
    EXPECT_TRUE(after.at("k2-2").isApprox(before.at("k2-2"), 1e-12));
    const Errors e = rig_errors(after, true_poses(temp_root() / "board4"), "k2-2",
                                ball(temp_root() / "board4", 0.3));
    EXPECT_LE(e.max_deg, 0.3);
    EXPECT_LE(e.max_rms_mm, 2.0);
}

TEST_F(Calibrate, NoBoardVisible) {
    rgbd::test::write_ellipsoid_off(temp_root() / "ball.off", 40, 20, 0.2, 0.2, 0.2);
    if (!fs::exists(temp_root() / "ballcap")) {
        ASSERT_EQ(run("$BIN/rgbd-synth ball.off -o ballcap --sensors 3 --height-m 0.4 -q").code, 0);
    }
    const Outcome r = run("$BIN/rgbd-calibrate ballcap -q -o never.json");
    rgbd::test::expect_failure(r, 1, "rgbd-calibrate", temp_root(), "never.json");
    EXPECT_NE(r.err.find("no board visible"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("ballcap"), std::string::npos) << r.err;
}

TEST_F(Calibrate, NamesASensorThatNeverSharesTheBoard) {
    // k2-3 keeps its images, but in frame sets of its own: it never sees the board together
    // with another sensor.
    const fs::path cap = temp_root() / "lonely";
    fs::remove_all(cap);
    fs::copy(temp_root() / "board4", cap, fs::copy_options::recursive);
    std::ifstream in(cap / "framesets.csv");
    std::string header, line, own;
    std::getline(in, header);
    std::ostringstream out;
    out << header << "\n";
    while (std::getline(in, line)) {
        std::vector<std::string> cells;
        std::stringstream ss(line);
        for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
        ASSERT_EQ(cells.size(), 7u);  // set, time, spread, 4 sensors
        own += std::to_string(1000 + std::stoi(cells[0])) + "," + cells[1] + ",0,-1,-1,-1," +
               cells[6] + "\n";
        cells[6] = "-1";
        for (std::size_t i = 0; i < cells.size(); ++i) out << (i ? "," : "") << cells[i];
        out << "\n";
    }
    in.close();
    std::ofstream(cap / "framesets.csv") << out.str() << own;
    const Outcome r = run("$BIN/rgbd-calibrate lonely -q -o never.json");
    rgbd::test::expect_failure(r, 1, "rgbd-calibrate", temp_root(), "never.json");
    EXPECT_NE(r.err.find("cannot connect k2-3"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("k2-1"), std::string::npos) << r.err;
}

TEST_F(Calibrate, BoardFileThatDoesNotMatch) {
    // Same layout, 100 mm squares instead of 80: markers are found, the pose is 25% too far,
    // and the depth says so.
    std::ofstream(temp_root() / "big.json")
        << R"({"squares_x": 7, "squares_y": 5, "square_m": 0.1, "marker_m": 0.075})";
    Outcome r = run("$BIN/rgbd-calibrate board4 -o never.json --board big.json -q");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("does not match"), std::string::npos) << r.err;
    // Another dictionary: no marker of the board.
    std::ofstream(temp_root() / "dict.json") << R"({"dictionary": "DICT_6X6_250"})";
    r = run("$BIN/rgbd-calibrate board4 -o never.json --board dict.json -q");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("no board visible"), std::string::npos) << r.err;
    // Not JSON, an unknown key, a missing file: errors naming the file.
    std::ofstream(temp_root() / "bad.json") << "{squares_x: 7";
    std::ofstream(temp_root() / "key.json") << R"({"squares": 7})";
    std::ofstream(temp_root() / "type.json") << R"({"squares_x": "seven"})";
    std::ofstream(temp_root() / "marker.json") << R"({"square_m": 0.05, "marker_m": 0.06})";
    std::ofstream(temp_root() / "array.json") << "[7, 5]\n";
    std::ofstream(temp_root() / "multi.json") << "{\n  \"squares_x\": 7,\n\n";
    for (const char* file : {"bad.json", "key.json", "type.json", "marker.json", "array.json",
                             "multi.json", "missing.json"}) {
        SCOPED_TRACE(file);
        r = run(std::string("$BIN/rgbd-calibrate board4 -q -o never.json --board ") + file);
        rgbd::test::expect_failure(r, 1, "rgbd-calibrate", temp_root(), "never.json");
        EXPECT_NE(r.err.find(file), std::string::npos) << r.err;
    }
}

TEST_F(Calibrate, BlurredBoardFailsCleanly) {
    if (!fs::exists(temp_root() / "blurred")) {
        ASSERT_EQ(run("$BIN/rgbd-synth --target charuco -q -o blurred --sensors 4 --frames 6 "
                      "--board-blur-px 8")
                      .code,
                  0);
    }
    const Outcome r = run("$BIN/rgbd-calibrate blurred -q -o never.json");
    rgbd::test::expect_failure(r, 1, "rgbd-calibrate", temp_root(), "never.json");
    // Either no marker survives the blur or the corners do not make a board.
    EXPECT_TRUE(r.err.find("blurred") != std::string::npos ||
                r.err.find("no board visible") != std::string::npos)
        << r.err;
}

TEST_F(Calibrate, RefineOnTheBust) {
    // Six sensors (the ring on which the pairwise stage of align_views once misregistered a
    // sensor, so --refine refused), 8 frame sets of the still bust combined per pixel.
    const fs::path mesh = fs::path(RGBD_SHARED_DATA) / "meshes/max_planck/max-planck.obj";
    if (!fs::exists(mesh)) GTEST_SKIP() << "shared data absent: " << mesh;
    if (!fs::exists(temp_root() / "bust")) {
        ASSERT_EQ(run("$BIN/rgbd-synth " + mesh.string() +
                      " -o bust --up y --height-m 0.45 --sensors 6 --frames 8 --seed 1 "
                      "--calib-error-deg 3 --calib-error-mm 30 -q")
                      .code,
                  0);
    }
    const Outcome r =
        run("$BIN/rgbd-calibrate bust --refine -o refined.json --metrics refine_m.json");
    ASSERT_EQ(r.code, 0) << r.err;
    for (const char* id : {"k2-1", "k2-5", "change_deg", "mean of 8 frame sets"})
        EXPECT_NE((r.out + r.err).find(id), std::string::npos) << id;
    EXPECT_EQ(nlohmann::json::parse(slurp(temp_root() / "refine_m.json"))["framesets_combined"], 8);
    const rgbd::Mesh surface = rgbd::io::read_mesh(temp_root() / "bust" / "gt" / "mesh.ply");
    std::vector<Eigen::Vector3d> points;
    for (const auto v : surface.vertices()) points.push_back(rgbd::to_eigen(surface.point(v)));
    const auto truth = true_poses(temp_root() / "bust");
    const Errors before =
        rig_errors(rig_poses(temp_root() / "bust" / "rig.json"), truth, "k2-0", points);
    const Errors after = rig_errors(rig_poses(temp_root() / "refined.json"), truth, "k2-0", points);
    EXPECT_GT(before.max_rms_mm, 20.0);
    EXPECT_GT(before.max_deg, 2.9);
    // The issue's targets (the 18-capture benchmark: worst 0.19 deg, 0.85 mm).
    EXPECT_LE(after.max_rms_mm, 1.5);
    EXPECT_LE(after.max_deg, 0.2);
    // Bad --sets: usage error, nothing written.
    const Outcome bad = run("$BIN/rgbd-calibrate bust --refine --sets 0 -o never.json");
    rgbd::test::expect_failure(bad, 2, "rgbd-calibrate", temp_root(), "never.json");
}
