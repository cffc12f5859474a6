// Contract tests of rgbd-mesh (cli/README.md, issue 7): methods and formats, --watertight closes
// the mesh, --target-faces is honoured, vertex colours reach the file, and bad input (empty
// stream, a non-finite coordinate, no normals with too few points, absurd --target-faces,
// unknown --method) gives a one-line error, the right exit code and no output file.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/support/tool_runner.hpp"

namespace fs = std::filesystem;

namespace {

RGBD_TOOL_TEST_SCRATCH("rgbd_mesh_test")

/// ASCII PLY stream document: Fibonacci samples of a sphere (radius 0.1 m) with outward
/// normals, red above z = 0 and blue below; `bad` replaces one coordinate by nan.
void write_sphere(const fs::path& path, int n, bool bad = false) {
    std::ofstream out(path);
    out << "ply\nformat ascii 1.0\ncomment rgbd:stream 1\ncomment rgbd:kind points\n"
           "comment rgbd:units m\ncomment rgbd:view.id 0\ncomment rgbd:view.frame world\n"
           "element vertex "
        << n
        << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n"
           "property float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\n"
           "property uchar blue\nend_header\n";
    const double golden = M_PI * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z);
        const double x = r * std::cos(golden * i), y = r * std::sin(golden * i);
        if (bad && i == n / 2)
            out << "nan";
        else
            out << 0.1 * x;
        out << " " << 0.1 * y << " " << 0.1 * z << " " << x << " " << y << " " << z
            << (z > 0 ? " 220 20 20\n" : " 20 20 220\n");
    }
}

class Mesh : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (!fs::exists(temp_root() / "sphere.ply")) write_sphere(temp_root() / "sphere.ply", 6000);
    }
};

/// Vertex and face counts of a mesh file, via rgbd-info --json.
nlohmann::json info(const std::string& file) {
    const Outcome r = run("$BIN/rgbd-info --json " + file);
    EXPECT_EQ(r.code, 0) << r.err;
    return nlohmann::json::parse(r.out);
}

}  // namespace

TEST_F(Mesh, HelpNamesMethodsAndOptions) {
    const Outcome help = run("$BIN/rgbd-mesh --help");
    EXPECT_EQ(help.code, 0);
    for (const char* word :
         {"--method", "front", "poisson", "advancing-front", "--watertight", "--target-faces",
          "--max-points", "--repair-self-intersections", "Example"})
        EXPECT_NE(help.out.find(word), std::string::npos) << word;
}

TEST_F(Mesh, WatertightClosesAndTargetFacesIsHonoured) {
    const Outcome r =
        run("$BIN/rgbd-mesh sphere.ply --watertight --target-faces 3000 --metrics m.json -o "
            "closed.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto m = nlohmann::json::parse(slurp(temp_root() / "m.json"));
    const auto& rec = m["mesh"]["reconstruction"];
    EXPECT_EQ(rec["method"], "front");
    EXPECT_EQ(rec["closed"], true);
    EXPECT_EQ(rec["border_edges"], 0);
    EXPECT_EQ(rec["colored"], true);
    EXPECT_LE(rec["faces"].get<std::size_t>(), 3000u);
    EXPECT_GE(rec["faces"].get<std::size_t>(), 2500u);
    const std::string ply = slurp(temp_root() / "closed.ply");
    EXPECT_NE(ply.find("property uchar red"), std::string::npos);
    EXPECT_NE(ply.find("element face"), std::string::npos);
}

TEST_F(Mesh, RepairSelfIntersectionsLeavesNoCrossingAndStaysClosed) {
    const Outcome r = run(
        "$BIN/rgbd-mesh sphere.ply --watertight --repair-self-intersections --metrics m.json -o "
        "repaired.ply");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto m = nlohmann::json::parse(slurp(temp_root() / "m.json"));
    const auto& rec = m["mesh"]["reconstruction"];
    EXPECT_EQ(rec["closed"], true);
    const auto& si = rec["self_intersections"];
    EXPECT_EQ(si["pairs_after"], 0) << si.dump();
    EXPECT_EQ(si["faces_after"], rec["faces"]) << si.dump();
}

TEST_F(Mesh, WritesObjAndOffAndEveryMethod) {
    for (const char* args : {"-o s.obj", "-o s.off", "--method poisson -o p.ply",
                             "--method advancing-front -o a.ply"}) {
        SCOPED_TRACE(args);
        const Outcome r = run(std::string("$BIN/rgbd-mesh sphere.ply -q ") + args);
        ASSERT_EQ(r.code, 0) << r.err;
    }
    EXPECT_LE(slurp(temp_root() / "s.off").find("OFF"), 1u);  // OFF, or COFF with colours
    EXPECT_NE(slurp(temp_root() / "s.obj").find("\nf "), std::string::npos);
    const auto j = info("s.off");
    EXPECT_GT(j[0]["documents"][0]["faces"].get<std::size_t>(), 5000u) << j.dump();
}

TEST_F(Mesh, BadInputGivesOneLineErrorAndNoOutput) {
    write_sphere(temp_root() / "nan.ply", 500, /*bad=*/true);
    write_sphere(temp_root() / "tiny.ply", 50);
    struct Case {
        const char* args;
        int code;
        const char* word;
    };
    for (const Case& c :
         {Case{"nan.ply", 1, "nan.ply"}, Case{"tiny.ply", 1, "100"},
          Case{"- < /dev/null", 1, "rgbd-mesh"}, Case{"sphere.ply --target-faces 2", 2, "target"},
          Case{"sphere.ply --target-faces -5", 2, "got -5"},
          Case{"sphere.ply --max-points -1", 2, "got -1"},
          Case{"sphere.ply --method marching-cubes", 2, "marching-cubes"},
          Case{"sphere.ply --max-points 7", 2, "max_points"}}) {
        SCOPED_TRACE(c.args);
        const Outcome r = run(std::string("$BIN/rgbd-mesh ") + c.args + " -o never.ply");
        rgbd::test::expect_failure(r, c.code, "rgbd-mesh", temp_root());
        EXPECT_NE(r.err.find(c.word), std::string::npos) << r.err;
    }
}
