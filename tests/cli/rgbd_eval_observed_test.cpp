// rgbd-eval --observed: on a small synthetic ring capture of an ellipsoid (exact rig poses),
// the true mesh explains the observations, a mesh moved by 10 cm does not, and a far-away box
// added to the true mesh is unsupported area of exactly its share; the subject labels of
// gt/<sensor>/segment/ select the labelled pixels only, and the noise labels of gt/<sensor>/labels/
// take the flying pixels and outliers out of them; bad inputs fail with one line.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io/mesh_io.hpp"
#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_eval_observed_test")

/// A capture DIR of 6 Kinect v2 at a quarter of their resolution around an ellipsoid (radii
/// 0.15, 0.25, 0.12 m before rgbd-synth scales it to 0.5 m high), seed 5, with rgbd-synth's
/// `options` (noise, calibration error).
void synth_ellipsoid(const std::string& dir, const std::string& options) {
    rgbd::test::write_ellipsoid_off(temp_root() / (dir + ".off"), 64, 32, 0.15, 0.25, 0.12);
    const Outcome r =
        run("$BIN/rgbd-synth " + dir + ".off -o " + dir +
            " --sensors 6 --height-m 0.5 --resolution-scale 0.25 --seed 5 -q " + options);
    EXPECT_EQ(r.code, 0) << r.err;
}

/// The capture, made once: rig poses exact, no noise (flying pixels at the silhouettes would be
/// observations no surface explains).
fs::path capture() {
    static const fs::path cap = [] {
        synth_ellipsoid("cap", "--calib-error-deg 0 --calib-error-mm 0 --noise none");
        return temp_root() / "cap";
    }();
    return cap;
}

nlohmann::json eval(const std::string& mesh, const std::string& extra = "") {
    const Outcome r = run("$BIN/rgbd-eval " + mesh + " --observed " + capture().string() + " " +
                          extra + " -o eval.json -q");
    EXPECT_EQ(r.code, 0) << r.err;
    return read_json(temp_root() / "eval.json");
}

double mesh_area(const rgbd::Mesh& mesh) {
    double area = 0;
    for (auto f : mesh.faces()) {
        std::vector<Eigen::Vector3d> c;
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh))
            c.push_back(rgbd::to_eigen(mesh.point(v)));
        area += 0.5 * (c[1] - c[0]).cross(c[2] - c[0]).norm();
    }
    return area;
}

TEST(RgbdEvalObserved, TrueMeshExplainsTheObservations) {
    ASSERT_TRUE(fs::exists(capture() / "gt" / "mesh.ply"));
    const auto e = eval("cap/gt/mesh.ply");
    const auto& o = e["observed"];
    ASSERT_TRUE(o.is_object()) << e.dump(2);
    EXPECT_EQ(o["tau_mm"].get<double>(), 20.0);
    EXPECT_GE(o["explained"].get<double>(), 0.95) << o.dump(2);
    // The ring sees the sides; the unseen caps (top, bottom) are all that may lack support.
    EXPECT_LT(o["unsupported_area_fraction"].get<double>(), 0.15) << o.dump(2);
    EXPECT_GT(o["covered"].get<double>(), 0.8) << o.dump(2);
    // rgbd-synth writes a truth label per depth pixel (gt/<sensor>/segment/): the subject's.
    EXPECT_EQ(o["subject"]["selection"], "labels");
    EXPECT_EQ(o["subject"]["views"].get<int>(), 6);
    EXPECT_GT(o["observed_points"].get<int>(), 1000);
    EXPECT_EQ(o["observed_points"], o["subject"]["points"]);
    // The detail tau: explained can only drop at a smaller tau.
    const auto& fine = o["at_5mm"];
    EXPECT_LE(fine["explained"].get<double>(), o["explained"].get<double>());
    EXPECT_NEAR(o["mesh_area_m2"].get<double>(),
                mesh_area(rgbd::io::read_mesh(capture() / "gt" / "mesh.ply")), 1e-6);
}

TEST(RgbdEvalObserved, MovedMeshDoesNotExplainThem) {
    rgbd::Mesh mesh = rgbd::io::read_mesh(capture() / "gt" / "mesh.ply");
    for (auto v : mesh.vertices()) mesh.point(v) = mesh.point(v) + rgbd::Vector_3(0.1, 0, 0);
    rgbd::io::write_mesh(temp_root() / "moved.ply", mesh);
    const double truth = eval("cap/gt/mesh.ply")["observed"]["explained"].get<double>();
    const auto o = eval("moved.ply")["observed"];
    EXPECT_LT(o["explained"].get<double>(), 0.5 * truth) << o.dump(2);
    EXPECT_GT(o["unsupported_area_fraction"].get<double>(), 0.3) << o.dump(2);
}

TEST(RgbdEvalObserved, SyntheticCapturesArePlacedWithTheirTruePoses) {
    // rgbd-synth's rig.json poses carry a calibration error; its truth does not. By default the
    // observations go where the sensors truly saw them (the truth mesh explains them); with
    // --observed-capture-poses, where the erroneous rig puts them (it explains far fewer).
    synth_ellipsoid("miscal", "--calib-error-deg 3 --calib-error-mm 40 --noise none");
    const auto judge = [](const std::string& extra) {
        const Outcome e = run("$BIN/rgbd-eval miscal/gt/mesh.ply --observed miscal " + extra +
                              " -o miscal.json -q");
        EXPECT_EQ(e.code, 0) << e.err;
        return read_json(temp_root() / "miscal.json")["observed"];
    };
    const auto truth = judge("");
    EXPECT_EQ(truth["subject"]["poses"], "given") << truth.dump(2);
    EXPECT_GE(truth["explained"].get<double>(), 0.95) << truth.dump(2);
    const auto rig = judge("--observed-capture-poses");
    EXPECT_EQ(rig["subject"]["poses"], "capture") << rig.dump(2);
    EXPECT_LT(rig["explained"].get<double>(), truth["explained"].get<double>() - 0.1)
        << rig.dump(2);
}

TEST(RgbdEvalObserved, FarBoxIsUnsupportedByItsShareOfTheArea) {
    const fs::path gt = capture() / "gt" / "mesh.ply";
    const auto base = eval("cap/gt/mesh.ply")["observed"];
    rgbd::Mesh mesh = rgbd::io::read_mesh(gt);
    // A 0.2 m cube 3 m from the object: 12 triangles, 0.24 m^2, no observation near it.
    const double s = 0.2;
    std::vector<rgbd::Mesh::Vertex_index> c;
    for (int i = 0; i < 8; ++i)
        c.push_back(mesh.add_vertex(
            rgbd::Point_3(3.0 + s * (i & 1), s * ((i >> 1) & 1), 3.0 + s * ((i >> 2) & 1))));
    const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                             {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) {
        mesh.add_face(c[q[0]], c[q[1]], c[q[2]]);
        mesh.add_face(c[q[0]], c[q[2]], c[q[3]]);
    }
    rgbd::io::write_mesh(temp_root() / "boxed.ply", mesh);
    const auto o = eval("boxed.ply")["observed"];
    const double a = base["mesh_area_m2"].get<double>(), box = 6 * s * s;
    EXPECT_NEAR(o["mesh_area_m2"].get<double>(), a + box, 1e-6);
    // Unsupported: the box plus what was unsupported before, as shares of the new area.
    const double expected = (box + base["unsupported_area_fraction"].get<double>() * a) / (a + box);
    EXPECT_NEAR(o["unsupported_area_fraction"].get<double>(), expected, 0.01) << o.dump(2);
    EXPECT_GT(expected, 0.1);  // the box is a sizeable share: the test would notice it missing
    // The observations themselves are explained as before.
    EXPECT_NEAR(o["explained"].get<double>(), base["explained"].get<double>(), 1e-9);
}

TEST(RgbdEvalObserved, SubjectLabelsSelectTheLabelledPixels) {
    // A copy of the capture with labels: subject (1) on the left half of every depth image,
    // background (3) on the right half.
    const fs::path copy = temp_root() / "labelled";
    fs::remove_all(copy);
    fs::copy(capture(), copy, fs::copy_options::recursive);
    int images = 0;
    for (const auto& sensor : fs::directory_iterator(copy)) {
        if (!fs::exists(sensor.path() / "depth")) continue;
        const fs::path out = copy / "gt" / sensor.path().filename() / "segment";
        fs::create_directories(out);
        for (const auto& f : fs::directory_iterator(sensor.path() / "depth")) {
            const cv::Mat depth = cv::imread(f.path().string(), cv::IMREAD_UNCHANGED);
            cv::Mat label(depth.size(), CV_8UC1, cv::Scalar(3));
            label.colRange(0, depth.cols / 2).setTo(1);
            cv::imwrite((out / f.path().filename()).string(), label);
            ++images;
        }
    }
    ASSERT_EQ(images, 6);
    const auto all = eval("cap/gt/mesh.ply")["observed"];
    const Outcome r = run("$BIN/rgbd-eval cap/gt/mesh.ply --observed labelled -o labels.json -q");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto o = read_json(temp_root() / "labels.json")["observed"];
    EXPECT_EQ(o["subject"]["selection"], "labels");
    // About half of the object's pixels (it sits in the middle of every image).
    const double share = o["observed_points"].get<double>() / all["observed_points"].get<double>();
    EXPECT_GT(share, 0.3);
    EXPECT_LT(share, 0.7);
    EXPECT_GE(o["explained"].get<double>(), 0.95);
    // One label image missing while the others exist: an error naming it.
    fs::remove(copy / "gt" / "k2-1" / "segment" / "000000.png");
    const Outcome missing = run("$BIN/rgbd-eval cap/gt/mesh.ply --observed labelled -q");
    EXPECT_EQ(missing.code, 1) << missing.err;
    EXPECT_NE(missing.err.find("segment/000000.png"), std::string::npos) << missing.err;
}

TEST(RgbdEvalObserved, NoisePixelsAreNoObservationOfTheSubject) {
    // With the default noise, rgbd-synth's flying pixels and random outliers keep the segment
    // label of the surface their ray hits, but their depth lies off every surface: its noise
    // labels (gt/<sensor>/labels/) take them out of the observed subject, so the truth explains
    // nearly all of what is left. Without the noise labels they count, and explain less.
    synth_ellipsoid("noisy", "--calib-error-deg 0 --calib-error-mm 0");
    const auto judge = [](const std::string& cap) {
        const Outcome e =
            run("$BIN/rgbd-eval " + cap + "/gt/mesh.ply --observed " + cap + " -o noisy.json -q");
        EXPECT_EQ(e.code, 0) << e.err;
        return read_json(temp_root() / "noisy.json")["observed"];
    };
    const auto labelled = judge("noisy");
    ASSERT_TRUE(labelled["subject"].contains("noise_excluded")) << labelled.dump(2);
    const auto excluded = labelled["subject"]["noise_excluded"].get<std::size_t>();
    EXPECT_GT(excluded, 10u) << labelled.dump(2);
    EXPECT_GE(labelled["explained"].get<double>(), 0.99) << labelled.dump(2);
    // The same capture without its noise labels: the excluded pixels are observations again.
    const fs::path bare = temp_root() / "noisy_bare";
    fs::remove_all(bare);
    fs::copy(temp_root() / "noisy", bare, fs::copy_options::recursive);
    for (const auto& sensor : fs::directory_iterator(bare / "gt"))
        if (sensor.is_directory()) fs::remove_all(sensor.path() / "labels");
    const auto unlabelled = judge("noisy_bare");
    EXPECT_EQ(unlabelled["observed_points"].get<std::size_t>(),
              labelled["observed_points"].get<std::size_t>() + excluded);
    EXPECT_LT(unlabelled["explained"].get<double>(), labelled["explained"].get<double>());
    // A noise label image of the wrong size: an error naming it.
    fs::create_directories(bare / "gt" / "k2-2" / "labels");
    cv::imwrite((bare / "gt" / "k2-2" / "labels" / "000000.png").string(),
                cv::Mat(3, 3, CV_8UC1, cv::Scalar(1)));
    const Outcome wrong = run("$BIN/rgbd-eval noisy_bare/gt/mesh.ply --observed noisy_bare -q");
    EXPECT_EQ(wrong.code, 1) << wrong.err;
    EXPECT_NE(wrong.err.find("labels/000000.png"), std::string::npos) << wrong.err;
}

TEST(RgbdEvalObserved, BadInputFailsWithOneLine) {
    capture();
    // No capture there.
    Outcome r = run("$BIN/rgbd-eval cap/gt/mesh.ply --observed nowhere -o never.json");
    rgbd::test::expect_failure(r, 1, "rgbd-eval", temp_root(), "never.json");
    EXPECT_NE(r.err.find("nowhere"), std::string::npos) << r.err;
    // A folder that is not a capture.
    fs::create_directories(temp_root() / "empty");
    r = run("$BIN/rgbd-eval cap/gt/mesh.ply --observed empty -o never.json");
    rgbd::test::expect_failure(r, 1, "rgbd-eval", temp_root(), "never.json");
    EXPECT_NE(r.err.find("empty"), std::string::npos) << r.err;
    // A mesh without faces.
    std::ofstream(temp_root() / "nofaces.off") << "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n";
    r = run("$BIN/rgbd-eval nofaces.off --observed cap -o never.json");
    rgbd::test::expect_failure(r, 1, "rgbd-eval", temp_root(), "never.json");
    EXPECT_NE(r.err.find("nofaces.off"), std::string::npos) << r.err;
    // A capture whose rig has no poses.
    const fs::path nopose = temp_root() / "nopose";
    fs::remove_all(nopose);
    fs::copy(capture(), nopose, fs::copy_options::recursive);
    auto rig = read_json(nopose / "rig.json");
    for (auto& s : rig["sensors"]) s.erase("world_from_depth");
    std::ofstream(nopose / "rig.json") << rig.dump(1);
    // (its truth would place the views: the rig's poses are asked for)
    r =
        run("$BIN/rgbd-eval cap/gt/mesh.ply --observed nopose --observed-capture-poses "
            "-o never.json");
    rgbd::test::expect_failure(r, 1, "rgbd-eval", temp_root(), "never.json");
    EXPECT_NE(r.err.find("has no pose"), std::string::npos) << r.err;
    // tsdf without --observed is a usage error.
    r = run("$BIN/rgbd-eval cap/gt/mesh.ply --points x.ply --baseline tsdf -o never.json");
    rgbd::test::expect_failure(r, 2, "rgbd-eval", temp_root(), "never.json");
}

}  // namespace
