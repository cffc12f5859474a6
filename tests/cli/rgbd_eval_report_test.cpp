// rgbd-eval --baseline screened-poisson (Open3D 0.16 via Debian's python3-open3d) and
// --report: on an ellipsoid with exact points, the baseline's meshes are evaluated like the
// result, side by side; the report page holds the pictures, and headless Chromium shows every
// picture (each PNG is found pixel for pixel in a screenshot of the page). Skips the baseline
// without python3-open3d and the screenshot without chromium.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;
using rgbd::test::Outcome;
using rgbd::test::slurp;

namespace {

constexpr double kA = 0.3, kB = 0.5, kC = 0.25;

fs::path work() {
    static const fs::path root = [] {
        const fs::path d = rgbd::test::scratch_dir("rgbd_eval_report_test");
        rgbd::test::write_ellipsoid_off(d / "ell.off", 96, 48, kA, kB, kC);
        rgbd::test::write_ellipsoid_off(
            d / "bumpy.off", 64, 32, kA, kB, kC,
            [](double th, double ph) { return 1.0 + 0.03 * std::sin(4 * ph) * std::sin(th); });
        // 12000 points on the ellipsoid with outward normals, with and without normals.
        std::ofstream with(d / "pts.xyz"), without(d / "pts_nonormals.xyz");
        const int n = 12000;
        for (int i = 0; i < n; ++i) {
            const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1 - z * z);
            const double phi = i * M_PI * (3.0 - std::sqrt(5.0));
            const double x = kA * r * std::cos(phi), y = kB * z, zz = kC * r * std::sin(phi);
            double nx = x / (kA * kA), ny = y / (kB * kB), nz = zz / (kC * kC);
            const double len = std::sqrt(nx * nx + ny * ny + nz * nz);
            with << x << " " << y << " " << zz << " " << nx / len << " " << ny / len << " "
                 << nz / len << "\n";
            without << x << " " << y << " " << zz << "\n";
        }
        return d;
    }();
    return root;
}

Outcome run(const std::string& command) { return rgbd::test::run_in(work(), command); }

bool have_open3d() {
    return std::system("/usr/bin/python3 -c 'import open3d' >/dev/null 2>&1") == 0;
}

/// Opens `rep`/index.html in headless Chromium, takes a screenshot and checks that every
/// picture appears in it pixel for pixel and shows something besides background.
void screenshot_shows_every_picture(const fs::path& rep, const std::vector<std::string>& pictures) {
    const fs::path shot = work() / "shot.png";
    fs::remove(shot);
    const Outcome r =
        run("timeout 120 /usr/bin/chromium --headless --no-sandbox --disable-gpu "
            "--hide-scrollbars --force-device-scale-factor=1 --user-data-dir=" +
            (work() / "chromium-profile").string() + " --screenshot=" + shot.string() +
            " --window-size=1100,1400 file://" + (rep / "index.html").string());
    ASSERT_TRUE(fs::exists(shot)) << r.err;
    const cv::Mat page = cv::imread(shot.string());
    ASSERT_FALSE(page.empty());
    // Not blank: a good part of the page is not white.
    cv::Mat grey, ink;
    cv::cvtColor(page, grey, cv::COLOR_BGR2GRAY);
    cv::threshold(grey, ink, 245, 255, cv::THRESH_BINARY_INV);
    EXPECT_GT(cv::countNonZero(ink), 0.05 * page.total());
    // Every picture appears on the page as it is (a near-exact template match), and shows
    // the object (not background only).
    for (const auto& p : pictures) {
        SCOPED_TRACE(p);
        const cv::Mat img = cv::imread((rep / p).string());
        cv::Mat score;
        cv::matchTemplate(page, img, score, cv::TM_SQDIFF_NORMED);
        double best = 0;
        cv::Point at;
        cv::minMaxLoc(score, &best, nullptr, &at, nullptr);
        EXPECT_LT(best, 0.01) << "not found in the screenshot";
        cv::Mat region_grey, region_ink;
        cv::cvtColor(page(cv::Rect(at, img.size())), region_grey, cv::COLOR_BGR2GRAY);
        cv::threshold(region_grey, region_ink, 250, 255, cv::THRESH_BINARY_INV);
        EXPECT_GT(cv::countNonZero(region_ink), 0.1 * img.total());
    }
}

}  // namespace

TEST(RgbdEvalBaseline, ScreenedPoissonSideBySide) {
    if (!have_open3d()) GTEST_SKIP() << "needs python3-open3d (apt-get install python3-open3d)";
    // Normals given: depths 6 and 7; estimated by Open3D: depth 7 only (keeps the test short).
    for (const std::string points : {"pts.xyz", "pts_nonormals.xyz"}) {
        SCOPED_TRACE(points);
        const bool given = points == "pts.xyz";
        const Outcome r = run("$BIN/rgbd-eval bumpy.off --reference ell.off --points " + points +
                              " --baseline screened-poisson --baseline-depths " +
                              (given ? "6,7" : "7") + " --samples 20000 -o e.json");
        ASSERT_EQ(r.code, 0) << r.err;
        const auto e = nlohmann::json::parse(slurp(work() / "e.json"));
        // The side-by-side table on stderr.
        EXPECT_NE(r.err.find("spr-d7"), std::string::npos) << r.err;
        ASSERT_TRUE(e.contains("baseline")) << e.dump(2);
        const auto& b = e["baseline"];
        EXPECT_EQ(b["normals"].get<std::string>().substr(0, 5), given ? "given" : "estim");
        ASSERT_EQ(b["runs"].size(), given ? 2u : 1u);
        for (const auto& run : b["runs"]) {
            EXPECT_GT(run["time_s"].get<double>(), 0.0);
            EXPECT_GT(run["triangles"].get<int>(), 500);
            // Poisson on exact, oriented points of an ellipsoid is close to it.
            EXPECT_GT(run["surface"]["fscore_5mm"].get<double>(), 0.9) << run.dump(2);
            EXPECT_LT(run["surface"]["chamfer_m"].get<double>(), 0.004) << run.dump(2);
            EXPECT_LT(run["input_distance"]["median_mm"].get<double>(), 5.0);
        }
        const auto& last = b["runs"][b["runs"].size() - 1];
        if (given) {
            // Depth 7 resolves the ellipsoid better than depth 6 and is the best depth.
            EXPECT_LT(last["surface"]["chamfer_m"].get<double>(),
                      b["runs"][0]["surface"]["chamfer_m"].get<double>());
            EXPECT_EQ(r.err.find("spr-d6") != std::string::npos, true) << r.err;
        }
        EXPECT_EQ(b["best_depth"].get<int>(), 7);
        // Ours: the bumpy ellipsoid (3% bumps: up to 9 mm off) is evaluated the same way.
        EXPECT_LT(e["surface"]["fscore_5mm"].get<double>(),
                  last["surface"]["fscore_5mm"].get<double>());
    }
}

TEST(RgbdEvalBaseline, RejectsBadRequests) {
    struct Case {
        std::string args;
        int code;
    };
    for (const Case& c : std::vector<Case>{
             {"bumpy.off --baseline screened-poisson", 2},           // no input points
             {"bumpy.off --points pts.xyz --baseline marching", 2},  // unknown peer
             {"bumpy.off --points pts.xyz --baseline screened-poisson --baseline-depths 3", 2},
             {"bumpy.off --points pts.xyz --baseline screened-poisson --baseline-trim 0.7", 2},
             {"bumpy.off --points ell.off --report rep_bad", 1},  // a mesh as input points
             {"bumpy.off --points missing.xyz --report rep_bad", 1},
             {"bumpy.off --report rep_bad --report-size 10x10", 2},
         }) {
        SCOPED_TRACE(c.args);
        const Outcome r = run("$BIN/rgbd-eval " + c.args);
        EXPECT_EQ(r.code, c.code) << r.err;
        EXPECT_EQ(rgbd::test::line_count(r.err), c.code == 2 ? 2 : 1) << r.err;  // usage: + hint
        EXPECT_FALSE(fs::exists(work() / "rep_bad"));
    }
}

TEST(RgbdEvalReport, PageWithPicturesOpensInChromium) {
    const bool baseline = have_open3d();
    const Outcome r =
        run("$BIN/rgbd-eval bumpy.off --reference ell.off --points pts.xyz --samples 20000 "
            "--report rep --report-size 320x240 -o e.json" +
            std::string(baseline ? " --baseline screened-poisson --baseline-depths 6" : ""));
    ASSERT_EQ(r.code, 0) << r.err;
    std::vector<std::string> pictures = {"input.png", "result.png", "result_error.png",
                                         "result_closeup.png", "result_closeup_error.png"};
    if (baseline) {
        pictures.push_back("baseline.png");
        pictures.push_back("baseline_error.png");
    }
    const fs::path rep = work() / "rep";
    ASSERT_TRUE(fs::exists(rep / "index.html"));
    ASSERT_TRUE(fs::exists(rep / "metrics.json"));
    const std::string html = slurp(rep / "index.html");
    for (const auto& p : pictures) {
        SCOPED_TRACE(p);
        ASSERT_TRUE(fs::exists(rep / p));
        EXPECT_NE(html.find("src=\"" + p + "\""), std::string::npos);
        const cv::Mat img = cv::imread((rep / p).string());
        EXPECT_EQ(img.rows, 240);
        // Heat maps get a colour bar strip on the right; colour pictures none (the colour
        // close-up was once drawn as a heat map: the result's distances were left on it).
        if (p.find("_error") != std::string::npos)
            EXPECT_GT(img.cols, 320);
        else
            EXPECT_EQ(img.cols, 320);
    }
    EXPECT_NE(html.find("fscore_5mm"), std::string::npos);  // the metrics table
    const auto m = nlohmann::json::parse(slurp(rep / "metrics.json"));
    EXPECT_EQ(m["report"]["heat_map"]["distance"], "distance to the reference");
    if (!fs::exists("/usr/bin/chromium"))
        GTEST_SKIP() << "needs /usr/bin/chromium for the screenshot (apt-get install chromium)";
    screenshot_shows_every_picture(rep, pictures);
}

TEST(RgbdEvalReport, ReplacesAReportButNothingElse) {
    const std::string command =
        "$BIN/rgbd-eval bumpy.off --points pts.xyz --report rep --report-size 64x48 -q";
    Outcome r = run(command);
    ASSERT_EQ(r.code, 0) << r.err;
    // Without a reference: the heat map shows the distance to the input points.
    const auto m = nlohmann::json::parse(slurp(work() / "rep" / "metrics.json"));
    EXPECT_EQ(m["report"]["heat_map"]["distance"], "distance to the input points");
    EXPECT_TRUE(m.contains("input_distance"));
    // Written again: the old report is replaced, nothing else is left behind.
    r = run(command);
    ASSERT_EQ(r.code, 0) << r.err;
    for (const auto& e : fs::directory_iterator(work()))
        EXPECT_EQ(e.path().filename().string().find(".rep."), std::string::npos) << e.path();
    // A folder that is not a report is not replaced.
    fs::create_directories(work() / "mine");
    std::ofstream(work() / "mine" / "notes.txt") << "keep me\n";
    r = run("$BIN/rgbd-eval bumpy.off --points pts.xyz --report mine");
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_EQ(rgbd::test::line_count(r.err), 1) << r.err;
    EXPECT_TRUE(fs::exists(work() / "mine" / "notes.txt"));
    EXPECT_FALSE(fs::exists(work() / "mine" / "index.html"));
}
