// Contract tests of rgbd-fill (cli/README.md): two views of a sphere with an occlusion hole (near
// the equator, which neither sensor faces) and an opening (facing sensor A, which looked
// through it): only the occlusion hole is filled, with synthetic points on the sphere, in one
// new document after the input ones; --detect-only --mark flags rim points and adds nothing;
// absurd parameters are usage errors; garbage, truncated and empty input are errors that leave
// no output.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "algorithms/holes/hole_detection.hpp"
#include "io/ply_stream.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_fill_test")

// 20 degrees above the equator: both sensors see it more obliquely than 60 degrees.
const Eigen::Vector3d kOcclusion = Eigen::Vector3d(std::cos(0.35), 0, std::sin(0.35));
const Eigen::Vector3d kOpening = Eigen::Vector3d(0, 0.3, 1).normalized();
constexpr double kHoleRad = 0.07;  // angular radius: 7 mm on the 0.1 m sphere

std::vector<rgbd::io::Document> read(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    rgbd::io::PlyStreamReader reader(in, path.string());
    std::vector<rgbd::io::Document> docs;
    rgbd::io::Document d;
    while (reader.next(d)) docs.push_back(std::move(d));
    return docs;
}

class RgbdFill : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        // Sphere r = 0.1 m, ~2 mm spacing; view A = upper half (z >= 0), seen from (0,0,1),
        // view B = lower half, seen from (0,0,-1); both in the world frame with their poses.
        rgbd::PointCloud a, b;
        for (auto* v : {&a, &b}) {
            v->view.frame = rgbd::ViewFrame::kWorld;
            v->add_colors();
        }
        a.view.id = 0;
        b.view.id = 1;
        rgbd::Pose pa = rgbd::Pose::Identity(), pb = rgbd::Pose::Identity();
        pa.translation() = Eigen::Vector3d(0, 0, 1);
        pa.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
        pb.translation() = Eigen::Vector3d(0, 0, -1);
        a.view.world_from_sensor = pa;
        b.view.world_from_sensor = pb;
        const int n = 30000;
        const double golden = M_PI * (3.0 - std::sqrt(5.0));
        for (int i = 0; i < n; ++i) {
            const double z = 1.0 - 2.0 * (i + 0.5) / n;
            const double r = std::sqrt(1.0 - z * z);
            const Eigen::Vector3d u(r * std::cos(golden * i), r * std::sin(golden * i), z);
            if (std::acos(u.dot(kOcclusion)) < kHoleRad || std::acos(u.dot(kOpening)) < kHoleRad)
                continue;
            rgbd::PointCloud& v = z >= 0 ? a : b;
            const auto idx = *v.points.insert(rgbd::to_point(0.1 * u));
            v.colors().set(idx, {200, 100, 50});
        }
        std::ofstream out(temp_root() / "views.ply", std::ios::binary);
        rgbd::io::write_points(out, a);
        rgbd::io::write_points(out, b);
    }
};

TEST_F(RgbdFill, FillsTheOcclusionHoleOnlyWithSyntheticPointsOnTheSurface) {
    Outcome r = run("$BIN/rgbd-fill views.ply --metrics m.json > filled.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto m = nlohmann::json::parse(slurp(temp_root() / "m.json"));
    const auto& d = m["documents"][0];
    EXPECT_EQ(d["loops"], 2) << d.dump();
    EXPECT_EQ(d["occlusion_loops"], 1) << d.dump();
    EXPECT_EQ(d["opening_loops"], 1) << d.dump();
    EXPECT_EQ(d["mechanism"], "interpolation");
    const auto docs = read(temp_root() / "filled.ply");
    ASSERT_EQ(docs.size(), 3u);
    EXPECT_EQ(docs[0].cloud.size() + docs[1].cloud.size(), d["points"].get<std::size_t>());
    const rgbd::PointCloud& added = docs[2].cloud;
    EXPECT_EQ(added.view.id, 2);
    EXPECT_EQ(added.view.frame, rgbd::ViewFrame::kWorld);
    ASSERT_GT(added.size(), 20u);
    EXPECT_EQ(added.size(), d["points_added"].get<std::size_t>());
    const auto synthetic = added.flag(rgbd::prop::kSynthetic);
    ASSERT_TRUE(synthetic);
    ASSERT_TRUE(added.has_colors());
    ASSERT_TRUE(added.points.has_normal_map());
    for (auto idx : added.points) {
        const Eigen::Vector3d p = rgbd::to_eigen(added.points.point(idx));
        EXPECT_EQ((*synthetic)[idx], 1);
        EXPECT_NEAR(p.norm(), 0.1, 0.0005);
        // In the hole, or within one spacing (0.02 rad) of its rim.
        EXPECT_LT(std::acos(p.normalized().dot(kOcclusion)), kHoleRad + 0.02);
        EXPECT_EQ(added.colors().get(idx), (rgbd::Rgb{200, 100, 50}));
        EXPECT_GT(rgbd::to_eigen(added.points.normal(idx)).dot(p.normalized()), 0.95);
    }
    // Without the poses both holes are filled.
    r = run("$BIN/rgbd-fill --ignore-poses views.ply --metrics m2.json > filled2.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto m2 = nlohmann::json::parse(slurp(temp_root() / "m2.json"));
    EXPECT_EQ(m2["documents"][0]["loops_filled"], 2);
    // --max-points: fewer measured points than the views hold are thinned first; the occlusion
    // hole is still found and filled on the sphere, and the report says to how many.
    const std::size_t measured = d["points"].get<std::size_t>();
    r = run("$BIN/rgbd-fill --max-points " + std::to_string(measured / 2) +
            " views.ply --metrics m3.json > filled3.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto d3 = nlohmann::json::parse(slurp(temp_root() / "m3.json"))["documents"][0];
    EXPECT_EQ(d3["points_measured"].get<std::size_t>(), measured) << d3.dump();
    EXPECT_LE(d3["thinned_to"].get<std::size_t>(), measured / 2) << d3.dump();
    EXPECT_EQ(d3["occlusion_loops"], 1) << d3.dump();
    const auto docs3 = read(temp_root() / "filled3.ply");
    ASSERT_EQ(docs3.size(), 3u);
    ASSERT_GT(docs3[2].cloud.size(), 5u);
    for (auto idx : docs3[2].cloud.points)
        EXPECT_NEAR(rgbd::to_eigen(docs3[2].cloud.points.point(idx)).norm(), 0.1, 0.0005);
}

TEST_F(RgbdFill, DetectOnlyMarksRimPointsAndAddsNothing) {
    Outcome r = run("$BIN/rgbd-fill --detect-only --mark views.ply -o marked.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto docs = read(temp_root() / "marked.ply");
    ASSERT_EQ(docs.size(), 2u);
    std::size_t flagged = 0, near_rim = 0;
    for (const auto& doc : docs) {
        const auto flag = doc.cloud.flag(rgbd::prop::kBoundary);
        ASSERT_TRUE(flag);
        for (auto idx : doc.cloud.points) {
            if (!(*flag)[idx]) continue;
            ++flagged;
            const Eigen::Vector3d u = rgbd::to_eigen(doc.cloud.points.point(idx)).normalized();
            const double a = std::min(std::acos(u.dot(kOcclusion)), std::acos(u.dot(kOpening)));
            near_rim += a < kHoleRad + 0.04;  // within 2 spacings of a rim
        }
    }
    EXPECT_GT(flagged, 40u);
    EXPECT_EQ(near_rim, flagged);
}

TEST_F(RgbdFill, EveryMechanismRuns) {
    for (const char* m : {"one", "four", "three", "interpolation"}) {
        SCOPED_TRACE(m);
        Outcome r = run(std::string("$BIN/rgbd-fill --mechanism ") + m +
                        " views.ply --metrics mm.json > f.ply");
        ASSERT_EQ(r.code, 0) << r.err;
        const auto d = nlohmann::json::parse(slurp(temp_root() / "mm.json"))["documents"][0];
        EXPECT_EQ(d["mechanism"], m);
        EXPECT_GT(d["points_added"].get<int>(), 10);
    }
}

TEST_F(RgbdFill, AbsurdParametersAreUsageErrors) {
    for (const char* opt : {"--mechanism five",
                            "--threshold 2",
                            "--threshold nan",
                            "--k 0",
                            "--weights 1,2",
                            "--weights 0,0,0",
                            "--spacing-m -1",
                            "--step 0",
                            "--max-sweeps 0",
                            "--visible-angle-deg 90",
                            "--small-diameter -3",
                            "--inpaint-pixel 0",
                            "--inpaint-pixel nan",
                            "--telea-radius -1",
                            "--top-fraction 2",
                            "--min-rim-radial 5",
                            "--max-ellipsoid-rms 0",
                            "--clearance -1",
                            "--max-fit-rms 0",
                            "--colour-inpaint exemplar",
                            "--patch 8",
                            "--patch 1",
                            "--search-window 0.5",
                            "--search-window nan",
                            "--max-points -1"}) {
        SCOPED_TRACE(opt);
        const Outcome r = run(std::string("$BIN/rgbd-fill ") + opt + " views.ply -o never.ply");
        rgbd::test::expect_failure(r, 2, "rgbd-fill", temp_root());
    }
}

// A head (ellipsoid, 7.5 x 8.5 x 11 cm, z up) seen by a level ring of 8 sensors at the top of
// the head, each view holding the points that face it most: the crown (normals within 35
// degrees of up) is missing by construction, the bottom is cut open at z = -6 cm. rgbd-fill
// closes the crown with synthetic head-top points (fill_mechanism 6) on the ellipsoid, and
// adds none below the top; --no-head-top --no-large adds no 5 / 6 point.
TEST(RgbdFillRing, FillsTheCrownThatTheRingNeverSaw) {
    const Eigen::Vector3d axes(0.075, 0.085, 0.11);
    std::vector<rgbd::PointCloud> views(8);
    for (int k = 0; k < 8; ++k) {
        const double a = 2 * M_PI * k / 8;
        const Eigen::Vector3d c(1.5 * std::cos(a), 1.5 * std::sin(a), 0.11);
        rgbd::Pose pose = rgbd::Pose::Identity();
        const Eigen::Vector3d zc = Eigen::Vector3d(-c.x(), -c.y(), 0).normalized();
        const Eigen::Vector3d yc(0, 0, -1);
        pose.linear().col(0) = yc.cross(zc);
        pose.linear().col(1) = yc;
        pose.linear().col(2) = zc;
        pose.translation() = c;
        views[k].view.id = k;
        views[k].view.frame = rgbd::ViewFrame::kWorld;
        views[k].view.world_from_sensor = pose;
        views[k].add_colors();
    }
    const int n = 60000;
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n;
        const double r = std::sqrt(1.0 - z * z);
        const Eigen::Vector3d p =
            Eigen::Vector3d(r * std::cos(golden * i), r * std::sin(golden * i), z)
                .cwiseProduct(axes);
        const Eigen::Vector3d nrm = p.cwiseQuotient(axes.cwiseProduct(axes)).normalized();
        if (p.z() < -0.06 || nrm.z() > std::cos(35 * M_PI / 180)) continue;
        double phi = std::atan2(nrm.y(), nrm.x());
        if (phi < 0) phi += 2 * M_PI;
        auto& v = views[static_cast<int>(std::lround(phi / (M_PI / 4))) % 8];
        const auto idx = *v.points.insert(rgbd::to_point(p));
        v.colors().set(idx, {90, 60, 40});
    }
    {
        std::ofstream out(temp_root() / "ring.ply", std::ios::binary);
        for (const auto& v : views) rgbd::io::write_points(out, v);
    }
    Outcome r = run("$BIN/rgbd-fill ring.ply --metrics ring.json -o ring_filled.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto d = nlohmann::json::parse(slurp(temp_root() / "ring.json"))["documents"][0];
    EXPECT_EQ(d["axis"]["from_sensors"], true) << d.dump();
    const auto docs = read(temp_root() / "ring_filled.ply");
    ASSERT_EQ(docs.size(), 9u);
    const rgbd::PointCloud& added = docs[8].cloud;
    const auto mech = added.flag(rgbd::prop::kFillMechanism);
    const auto synthetic = added.flag(rgbd::prop::kSynthetic);
    ASSERT_TRUE(mech && synthetic);
    std::size_t crown = 0;
    double worst = 0;
    for (auto idx : added.points) {
        EXPECT_EQ((*synthetic)[idx], 1);
        if ((*mech)[idx] != 6) continue;
        ++crown;
        const Eigen::Vector3d p = rgbd::to_eigen(added.points.point(idx));
        const Eigen::Vector3d q = p.cwiseQuotient(axes);
        const Eigen::Vector3d g = q.cwiseQuotient(axes) / q.norm();
        worst = std::max(worst, std::abs(q.norm() - 1) / g.norm());
        EXPECT_GT(p.z(), 0.05);
    }
    EXPECT_GT(crown, 1000u) << d.dump();  // the crown cap is about 80 cm^2: ~2000 points
    EXPECT_LT(worst, 0.003);
    EXPECT_EQ(crown, d["head_top"]["points_added"].get<std::size_t>());
    EXPECT_EQ(d["head_top"]["colour"]["method"], "criminisi") << d.dump();
    r = run("$BIN/rgbd-fill ring.ply --no-head-top --no-large -o ring_small.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    for (const auto& doc : read(temp_root() / "ring_small.ply")) {
        const auto m = doc.cloud.flag(rgbd::prop::kFillMechanism);
        if (!m) continue;
        for (auto idx : doc.cloud.points) EXPECT_LE((*m)[idx], 4);
    }
}

TEST_F(RgbdFill, BadInputIsAnErrorWithoutOutput) {
    const std::string views = slurp(temp_root() / "views.ply");
    std::ofstream(temp_root() / "truncated.ply", std::ios::binary)
        << views.substr(0, views.size() / 3);
    std::ofstream(temp_root() / "nan.xyz") << "0 0 0\n1 0 0\nnan 1 0\n0 1 1\n1 1 1\n";
    std::ofstream(temp_root() / "garbage.ply") << "not a ply file\n";
    for (const char* file : {"truncated.ply", "nan.xyz", "garbage.ply"}) {
        SCOPED_TRACE(file);
        const Outcome r = run(std::string("$BIN/rgbd-fill ") + file + " -o never.ply");
        rgbd::test::expect_failure(r, 1, "rgbd-fill", temp_root());
        EXPECT_NE(r.err.find(file), std::string::npos) << r.err;
    }
    Outcome empty = run("$BIN/rgbd-fill - < /dev/null > out.ply");
    EXPECT_EQ(empty.code, 1) << empty.err;
    // Three points: passed through with a warning, nothing added.
    std::ofstream(temp_root() / "three.xyz") << "0 0 0\n1 0 0\n0 1 0\n";
    Outcome tiny = run("$BIN/rgbd-fill three.xyz > tiny.ply");
    EXPECT_EQ(tiny.code, 0) << tiny.err;
    EXPECT_NE(tiny.err.find("warning"), std::string::npos);
    EXPECT_EQ(read(temp_root() / "tiny.ply").size(), 1u);
}

}  // namespace
