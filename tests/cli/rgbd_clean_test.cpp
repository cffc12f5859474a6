// Contract tests of rgbd-clean's adaptive methods (cli/README.md): --distance is the default on
// organised views, --distance on a view without a grid is an error that suggests --density,
// --density runs on the aligned view stream and keeps the views, --mark == delete, absurd
// parameters are usage errors (exit 2), empty input passes.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_clean_test")

nlohmann::json metrics(const std::string& file) {
    return nlohmann::json::parse(slurp(temp_root() / file));
}

/// rgbd-clean OPTIONS on `input` (output NAME.ply, --metrics m_NAME.json): the per-document
/// metrics, empty (and a test failure) when the run failed.
nlohmann::json clean_documents(const std::string& options, const std::string& name,
                               const std::string& input = "views.ply") {
    const Outcome r = run("$BIN/rgbd-clean " + options + " " + input + " --metrics m_" + name +
                          ".json > " + name + ".ply");
    EXPECT_EQ(r.code, 0) << r.err;
    return r.code == 0 ? metrics("m_" + name + ".json")["documents"] : nlohmann::json::array();
}

/// The per-view metrics of rgbd-clean with options `a` (output A.ply) and with options `b`
/// (B.ply) on views.ply, paired view by view: empty (and a test failure) unless each run gives
/// a document for each of the fixture's 4 views.
std::vector<std::pair<nlohmann::json, nlohmann::json>> compare_views(const std::string& a,
                                                                     const std::string& a_name,
                                                                     const std::string& b,
                                                                     const std::string& b_name) {
    const auto first = clean_documents(a, a_name);
    const auto second = clean_documents(b, b_name);
    EXPECT_EQ(first.size(), 4u);
    EXPECT_EQ(second.size(), 4u);
    std::vector<std::pair<nlohmann::json, nlohmann::json>> views;
    if (first.size() == 4 && second.size() == 4)
        for (std::size_t v = 0; v < 4; ++v) views.emplace_back(first[v], second[v]);
    return views;
}

/// A 4-sensor ring capture of an ellipsoid, rendered once; views.ply = its organised views.
class RgbdClean : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (fs::exists(temp_root() / "views.ply")) return;
        rgbd::test::write_ellipsoid_off(temp_root() / "blob.off", 48, 24, 0.3, 0.5, 0.25);
        Outcome r =
            run("$BIN/rgbd-synth blob.off -o cap --sensors 4 --height-m 0.5 --seed 3 -q && "
                "$BIN/rgbd-cloud cap -q > views.ply");
        ASSERT_EQ(r.code, 0) << r.err;
    }
    // A fixture that failed must fail the tests, not skip them.
    void SetUp() override { ASSERT_TRUE(fs::exists(temp_root() / "views.ply")) << "no capture"; }
};

TEST_F(RgbdClean, DistanceIsTheDefaultOnOrganisedViews) {
    const auto by_default = clean_documents("", "default");
    clean_documents("--distance", "distance");
    const Outcome same = run(
        "cmp <(grep -av \"rgbd:history\" default.ply) <(grep -av \"rgbd:history\" distance.ply)");
    EXPECT_EQ(same.code, 0) << same.out;  // identical apart from the history line
    ASSERT_EQ(by_default.size(), 4u);
    for (const auto& d : by_default) {
        EXPECT_EQ(d["method"], "distance");
        EXPECT_GT(d["removed"].get<int>(), 0);
    }
}

TEST_F(RgbdClean, MarkEqualsDelete) {
    const auto views = compare_views("--distance --mark", "marked", "--distance", "deleted");
    // Both outputs are valid streams.
    const Outcome info = run("$BIN/rgbd-info marked.ply deleted.ply");
    EXPECT_EQ(info.code, 0) << info.err;
    for (const auto& [marked, deleted] : views) {
        EXPECT_EQ(marked["marked"], deleted["removed"]);
        EXPECT_EQ(marked["input_points"], deleted["input_points"]);
    }
}

// --knn-test adds Pass B: it runs, reports its threshold and can only remove more.
TEST_F(RgbdClean, KnnTestAddsThePassBStatistic) {
    for (const auto& [plain, knn] :
         compare_views("--distance", "plain", "--distance --knn-test", "knn")) {
        EXPECT_EQ(plain["statistical"], 0);
        EXPECT_TRUE(knn.contains("r_threshold"));
        EXPECT_GE(knn["removed"].get<int>(), plain["removed"].get<int>());
    }
}

TEST_F(RgbdClean, DistanceWithoutGridSuggestsDensity) {
    // rgbd-align --merge output has no grid.
    Outcome r =
        run("$BIN/rgbd-align views.ply --merge -q > merged.ply && "
            "$BIN/rgbd-clean --distance merged.ply > x.ply");
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_NE(r.err.find("--density"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("view"), std::string::npos) << r.err;
}

TEST_F(RgbdClean, DensityOnAlignedViewsKeepsTheViews) {
    const Outcome aligned =
        run("$BIN/rgbd-clean --distance views.ply | $BIN/rgbd-align -q > aligned.ply");
    ASSERT_EQ(aligned.code, 0) << aligned.err;
    const auto density = clean_documents("--density", "density", "aligned.ply");
    ASSERT_EQ(density.size(), 1u);
    EXPECT_EQ(density[0]["reference"], "sensors");
    EXPECT_EQ(density[0]["views"].size(), 4u);
    const Outcome info = run("$BIN/rgbd-info --json density.ply");
    EXPECT_NE(info.out.find("\"history\""), std::string::npos) << info.err;
}

// On a super-resolved, aligned stream the density stage judges the super-resolved points
// against the measured points they were made from (reported as synthetic_followers);
// --judge-synthetic judges every point on its own, and belongs to --density.
TEST_F(RgbdClean, JudgeSyntheticJudgesSuperResolvedPointsOnTheirOwn) {
    const Outcome up =
        run("$BIN/rgbd-clean --distance views.ply -q | $BIN/rgbd-upsample --capture cap -q | "
            "$BIN/rgbd-align -q > upsampled.ply");
    ASSERT_EQ(up.code, 0) << up.err;
    const auto parents = clean_documents("--density", "parents", "upsampled.ply");
    const auto alone = clean_documents("--density --judge-synthetic", "alone", "upsampled.ply");
    ASSERT_EQ(parents.size(), 1u);
    ASSERT_EQ(alone.size(), 1u);
    ASSERT_TRUE(parents[0].contains("synthetic_followers")) << parents[0].dump();
    EXPECT_GT(parents[0]["synthetic_followers"].get<int>(), 1000) << parents[0].dump();
    EXPECT_FALSE(alone[0].contains("synthetic_followers")) << alone[0].dump();
    EXPECT_EQ(parents[0]["input_points"], alone[0]["input_points"]);
    const Outcome wrong = run("$BIN/rgbd-clean --distance --judge-synthetic views.ply > w.ply");
    EXPECT_EQ(wrong.code, 2) << wrong.err;
    EXPECT_NE(wrong.err.find("judge-synthetic"), std::string::npos) << wrong.err;
}

// --high-recall is the stricter operating point: it removes more; an explicit option still
// wins over its preset value.
TEST_F(RgbdClean, HighRecallRemovesMoreAndExplicitOptionsWin) {
    const auto f1 = clean_documents("--distance", "f1");
    const auto hr = clean_documents("--distance --high-recall", "hr");
    const auto back = clean_documents(
        "--distance --high-recall --c-min 2 --c-min-wide 3 --keep-knn 3 --line-sigmas 3 "
        "--dense-min 16",
        "back");
    ASSERT_EQ(f1.size(), 4u);
    ASSERT_EQ(hr.size(), 4u);
    ASSERT_EQ(back.size(), 4u);
    int removed_f1 = 0, removed_hr = 0;
    for (std::size_t v = 0; v < 4; ++v) {
        removed_f1 += f1[v]["removed"].get<int>();
        removed_hr += hr[v]["removed"].get<int>();
        EXPECT_EQ(back[v]["removed"], f1[v]["removed"]);
    }
    EXPECT_GT(removed_hr, removed_f1);
}

// --smooth keeps what --distance keeps and moves the survivors along their rays; on a view
// without a grid it is an error naming the view.
TEST_F(RgbdClean, SmoothMovesTheSurvivorsAndDeletesNothingMore) {
    for (const auto& [rough, smooth] :
         compare_views("--distance", "rough", "--distance --smooth", "smooth")) {
        EXPECT_EQ(smooth["removed"], rough["removed"]);
        const auto& s = smooth["smooth"];
        EXPECT_GT(s["moved"].get<int>(), 0);
        EXPECT_GT(s["mean_shift_mm"].get<double>(), 0.0);
        EXPECT_EQ(s["input_points"].get<int>() + rough["removed"].get<int>(),
                  rough["input_points"].get<int>());
    }
    Outcome merged =
        run("$BIN/rgbd-align views.ply --merge -q > merged_s.ply && "
            "$BIN/rgbd-clean --smooth merged_s.ply > y.ply");
    EXPECT_EQ(merged.code, 1) << merged.err;
    EXPECT_NE(merged.err.find("organised"), std::string::npos) << merged.err;
}

TEST_F(RgbdClean, AbsurdParametersAreUsageErrors) {
    for (const std::string args :
         {"--distance --c-min 25", "--distance --line-sigmas -1", "--distance --dense-min 30",
          "--distance --theta-max-deg 95", "--distance --alpha -2", "--density --beta -1",
          "--density --k 1", "--noise-model kinect3", "--distance --density",
          "--reference global --density", "--n-speckle -5", "--density --smooth",
          "--statistical --smooth", "--density --consensus-ratio 2",
          "--density --consensus-sigmas 0", "--density --consensus-sigmas nan",
          "--distance --c-min-wide 49", "--distance --keep-knn -1", "--distance --keep-k 0"}) {
        SCOPED_TRACE(args);
        Outcome r = run("$BIN/rgbd-clean " + args + " < /dev/null");
        EXPECT_EQ(r.code, 2) << r.err;
    }
}

TEST_F(RgbdClean, EmptyStreamOfEmptyViewsPasses) {
    // Crop everything away: the views stay, with no points.
    Outcome r =
        run("$BIN/rgbd-cloud cap --crop-radius-m 0.001 -q > empty.ply && "
            "$BIN/rgbd-clean --distance empty.ply -q > e1.ply && "
            "$BIN/rgbd-clean --density empty.ply -q > e2.ply");
    EXPECT_EQ(r.code, 0) << r.err;
}

}  // namespace
