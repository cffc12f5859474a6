// rgbd-eval --observed --baseline tsdf,screened-poisson (Open3D 0.16 via Debian's
// python3-open3d): on a small synthetic ring capture of an ellipsoid, both peers run on the
// observed subject, are scored by the same observed metrics beside ours and explain the
// observations; the report page gets the observed table; no temporary file is left. Skips
// without python3-open3d.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_eval_observed_baseline_test")

TEST(RgbdEvalObservedBaseline, TsdfAndScreenedPoissonAreScoredBesideOurs) {
    if (std::system("/usr/bin/python3 -c 'import open3d' >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "python3-open3d is not installed";
    rgbd::test::write_ellipsoid_off(temp_root() / "ell.off", 64, 32, 0.15, 0.25, 0.12);
    Outcome r =
        run("$BIN/rgbd-synth ell.off -o cap --sensors 6 --height-m 0.5 --resolution-scale 0.25 "
            "--calib-error-deg 0 --calib-error-mm 0 --seed 5 -q");
    ASSERT_EQ(r.code, 0) << r.err;
    r =
        run("$BIN/rgbd-eval cap/gt/mesh.ply --observed cap --baseline tsdf,screened-poisson "
            "--report rep -o eval.json -q");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto e = read_json(temp_root() / "eval.json");
    ASSERT_TRUE(e.contains("baselines")) << e.dump(2);
    for (const char* name : {"tsdf", "screened_poisson"}) {
        SCOPED_TRACE(name);
        ASSERT_TRUE(e["baselines"].contains(name)) << e.dump(2);
        const auto& b = e["baselines"][name];
        EXPECT_GT(b["time_s"].get<double>(), 0.0);
        EXPECT_GT(b["triangles"].get<int>(), 100);
        EXPECT_GT(b["observed"]["explained"].get<double>(), 0.8) << b.dump(2);
        // Scored on the same observations as ours.
        EXPECT_EQ(b["observed"]["observed_points"], e["observed"]["observed_points"]);
    }
    const std::string page = slurp(temp_root() / "rep" / "index.html");
    EXPECT_NE(page.find("Open3D tsdf"), std::string::npos);
    EXPECT_NE(page.find("Open3D screened_poisson"), std::string::npos);
    EXPECT_FALSE(fs::exists(fs::temp_directory_path() /
                            ("rgbd-eval-observed-" + std::to_string(::getpid()))));
}

}  // namespace
