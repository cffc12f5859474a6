// Turntable acceptance (issue 23): rgbd-reconstruct's default job on a small synthetic SR300
// turntable capture of the Max Planck bust from ../shared/data (25 cm, 12 stops, half the
// sensor's resolution per side to keep it short, the object on a platter, the true axis
// tilted 2 deg and shifted 10 mm from the nominal one of frames.csv, stop angles off by
// N(0, 0.5 deg)): a closed coloured mesh, the platter removed, the axis error corrected by the
// alignment, the stops used listed, accuracy within bounds (the benchmark's full-resolution
// targets with margins). Skips without ../shared/data.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "io/mesh_io.hpp"
#include "tests/support/shared_data.hpp"
#include "tests/support/tool_runner.hpp"
#include "toolkit/mesh.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_turntable_test")

/// rgbd-synth's half-resolution SR300 turntable of the Max Planck bust (25 cm, on a platter,
/// the axis 2 deg / 10 mm off) into `folder`, with `extra` options.
rgbd::test::Outcome render_turntable(const fs::path& mesh, const std::string& folder,
                                     const std::string& extra) {
    return run("$BIN/rgbd-synth " + mesh.string() + " -o " + folder +
               " --rig turntable --height-m 0.25 --stand --resolution-scale 0.5"
               " --axis-tilt-deg 2 --axis-shift-mm 10 -q " +
               extra);
}

}  // namespace

TEST(Turntable, PlatterRemovedAxisCorrectedClosedAndAccurate) {
    const fs::path mesh = rgbd::test::shared_data("meshes/max_planck/max-planck.obj");
    RGBD_SKIP_WITHOUT(mesh);
    ASSERT_EQ(render_turntable(mesh, "tt", "--stops 12 --angle-noise-deg 0.5 --seed 3").code, 0);
    ASSERT_EQ(run("$BIN/rgbd-reconstruct tt -o tt.ply --report tt_report -q").code, 0);
    const auto m = read_json(temp_root() / "tt_report" / "metrics.json");

    // Closed and coloured.
    EXPECT_TRUE(m["mesh"]["reconstruction"]["closed"].get<bool>());
    const rgbd::Mesh result = rgbd::io::read_mesh(temp_root() / "tt.ply");
    EXPECT_TRUE(rgbd::vertex_colors(result).has_value());

    // The platter: found, removed, nothing of it left in the mesh. The truth's lowest point is
    // the platter's top (the world is the object frame at stop 0, z up).
    // The object extraction finds the platter's top as the ground (the lowest large flat plane
    // facing up, refitted per stop) and removes it before the alignment; the stand stage after
    // the alignment removes whatever it left. The closed base lies on the platter.
    const bool ground = m["extraction"]["ground"]["found"].get<bool>();
    const bool stand = m.contains("stand") && m["stand"].value("found", false);
    ASSERT_TRUE(ground || stand) << m["extraction"]["ground"].dump() << m["stand"].dump();
    const double removed = (ground ? m["extraction"]["ground"]["removed"].get<double>() : 0.0) +
                           (stand ? m["stand"]["removed"].get<double>() : 0.0);
    EXPECT_GT(removed, 10000);
    if (ground) EXPECT_EQ(m["mesh"]["reconstruction"]["holes"]["base"]["kind"], "ground");
    const rgbd::Mesh truth = rgbd::io::read_mesh(temp_root() / "tt/gt/mesh.ply");
    double truth_min = 1e9, result_min = 1e9;
    for (auto v : truth.vertices()) truth_min = std::min(truth_min, truth.point(v).z());
    for (auto v : result.vertices()) result_min = std::min(result_min, result.point(v).z());
    EXPECT_GT(result_min, truth_min - 0.002) << "mesh reaches below the platter's top";

    // Close-up pictures of the fine detail in the report.
    for (const char* pic : {"result_closeup.png", "result_closeup_error.png"})
        EXPECT_TRUE(fs::exists(temp_root() / "tt_report" / pic)) << pic;

    // The stops used: all 12, in frame order, with their registration verdicts.
    ASSERT_EQ(m["views_used"].size(), 12u);
    for (std::size_t i = 0; i < 12; ++i) {
        EXPECT_EQ(m["views_used"][i]["frame_index"].get<int>(), static_cast<int>(i));
        EXPECT_EQ(m["views_used"][i]["verdict"], "PASS") << m["views_used"][i].dump();
    }

    // The rough axis (2 deg, 10 mm) corrected by the alignment.
    EXPECT_LT(m["evaluation"]["poses"]["max_rotation_deg"].get<double>(), 0.5);
    EXPECT_LT(m["evaluation"]["poses"]["max_translation_mm"].get<double>(), 2.5);

    // Accuracy (issue targets at full resolution: F@1mm >= 0.90, invented <= 1%, completeness
    // mean <= 0.5 mm; here half resolution, with margins).
    const auto& s = m["evaluation"]["surface"];
    EXPECT_GE(s["fscore_1mm"].get<double>(), 0.85) << s.dump(2);
    EXPECT_LE(s["completeness_mean_m"].get<double>(), 0.0006) << s.dump(2);
    EXPECT_LE(s["invented_surface_fraction"].get<double>(), 0.02) << s.dump(2);
}

// The README's pipe gives rgbd-reconstruct's mesh on a turntable capture too: rgbd-cloud
// writes each view's sensor noise model (SR300 here) for rgbd-clean --noise-model auto, and
// rgbd-align removes the platter after the alignment and writes its plane into the views for
// rgbd-mesh to carry the walls down to, as rgbd-reconstruct does in one process. Before, the
// pipe cleaned with the Kinect v2 model and kept the platter: another mesh.
TEST(Turntable, PipeAndOneCommandGiveTheSameMesh) {
    const fs::path mesh = rgbd::test::shared_data("meshes/max_planck/max-planck.obj");
    RGBD_SKIP_WITHOUT(mesh);
    ASSERT_EQ(render_turntable(mesh, "tp", "--stops 8 --seed 4").code, 0);
    const Outcome piped =
        run("$BIN/rgbd-cloud tp -q | $BIN/rgbd-clean --distance -q | $BIN/rgbd-upsample -q | "
            "$BIN/rgbd-align -q | tee aligned.ply | $BIN/rgbd-clean --density -q | "
            "$BIN/rgbd-fill -q | $BIN/rgbd-mesh --watertight -o piped.ply -q");
    ASSERT_EQ(piped.code, 0) << piped.err;
    ASSERT_EQ(run("$BIN/rgbd-reconstruct tp -o one.ply -q").code, 0);
    const auto body = [](const fs::path& file) {
        const std::string bytes = slurp(temp_root() / file);
        return bytes.substr(bytes.find("end_header\n"));
    };
    EXPECT_TRUE(body("piped.ply") == body("one.ply"));
    // The views carry the noise model and the support plane; --stand keep writes no stand.
    const std::string aligned = slurp(temp_root() / "aligned.ply");
    EXPECT_NE(aligned.find("comment rgbd:sensor.noise_model sr300"), std::string::npos);
    // The support plane travels with the views: the extraction's ground, or the stand's.
    EXPECT_TRUE(aligned.find("comment rgbd:ground.plane ") != std::string::npos ||
                aligned.find("comment rgbd:stand.plane ") != std::string::npos);
    const Outcome kept =
        run("$BIN/rgbd-cloud tp -q --frames 0:3 | $BIN/rgbd-align --stand keep -q > kept.ply");
    ASSERT_EQ(kept.code, 0) << kept.err;
    EXPECT_EQ(slurp(temp_root() / "kept.ply").find("rgbd:stand.plane"), std::string::npos);
    EXPECT_EQ(run("$BIN/rgbd-align --stand sideways -q < aligned.ply > /dev/null").code, 2);
}
