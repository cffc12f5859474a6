// pipeline::reconstruct, the chain rgbd-reconstruct runs, as a library call: on a synthetic
// capture of a sphere seen from all sides (examples/example_data.hpp, exact depth, 8 cameras
// above and below) the mesh is closed and on the sphere, the stage rows chain (each stage's points
// in are the previous one's points out), timings() is the rows' times, --skip leaves rows out, and
// bad options or frame sets are InputErrors.
#include "pipeline/reconstruct.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "examples/example_data.hpp"
#include "tests/support/tool_runner.hpp"
#include "toolkit/error.hpp"

namespace {

const rgbd::io::Capture& capture() {
    static const rgbd::io::Capture c = rgbd::io::open_capture(
        examples::make_capture(rgbd::test::scratch_dir("rgbd_pipeline_test"), 8,
                               /*above_and_below=*/true));
    return c;
}

TEST(Reconstruct, TheMeshMatchesTheSphereAndTheStagesChain) {
    rgbd::pipeline::ReconstructOptions options;
    const auto frames = rgbd::pipeline::frameset_frames(capture(), 0);
    ASSERT_EQ(frames.size(), 8u);
    const auto result = rgbd::pipeline::reconstruct(capture(), frames, options);
    // Every mesh vertex lies on the sphere (closing patches included, within 5 mm).
    std::size_t off = 0;
    for (const auto v : result.mesh.vertices()) {
        const auto& p = result.mesh.point(v);
        off += std::abs(std::hypot(p.x(), p.y(), p.z()) - examples::kRadius) > 0.005;
    }
    EXPECT_GT(result.mesh.number_of_faces(), 1000u);
    std::size_t border = 0;
    for (const auto h : result.mesh.halfedges()) border += result.mesh.is_border(h);
    EXPECT_EQ(border, 0u) << "the default (watertight) mesh is closed";
    EXPECT_LT(off, result.mesh.number_of_vertices() / 50) << off << " vertices off the sphere";
    // Rows: clouds, extract, distance, (upsample: colour not finer, 0 views), align, density,
    // fill, mesh.
    std::vector<std::string> names;
    for (const auto& row : result.stages) names.push_back(row.stage);
    EXPECT_EQ(names, (std::vector<std::string>{"clouds", "extract", "distance", "upsample", "align",
                                               "density", "fill", "mesh"}));
    for (std::size_t i = 1; i < result.stages.size(); ++i)
        EXPECT_EQ(result.stages[i].points_in, result.stages[i - 1].points_out)
            << result.stages[i].stage;
    EXPECT_LE(result.stages[1].points_out, result.stages[1].points_in);  // extraction removes
    EXPECT_LE(result.stages[2].points_out, result.stages[2].points_in);  // cleaning removes
    const rgbd::Report timings = result.timings();
    ASSERT_EQ(timings.size(), result.stages.size());
    for (const auto& row : result.stages) EXPECT_EQ(timings[row.stage].get<double>(), row.time_s);
    EXPECT_EQ(result.stages_report().size(), result.stages.size());
    EXPECT_EQ(result.poses.size(), 8u);
    EXPECT_EQ(result.report["counts"]["mesh_faces"], result.mesh.number_of_faces());
}

TEST(Reconstruct, SkippedStagesLeaveNoRowAndHooksSeeEveryStage) {
    rgbd::pipeline::ReconstructOptions options;
    options.skip = {"distance", "upsample", "density", "fill"};
    options.mesh.watertight = false;
    std::vector<std::string> begun, saved;
    rgbd::pipeline::ReconstructHooks hooks;
    hooks.stage_begin = [&](const std::string& s) {
        begun.push_back(s);
        return rgbd::Progress{};
    };
    hooks.views_after = [&](int, const std::string& s, const std::vector<rgbd::PointCloud>&) {
        saved.push_back(s);
    };
    const auto result = rgbd::pipeline::reconstruct(
        capture(), rgbd::pipeline::frameset_frames(capture(), 0), options, hooks);
    std::vector<std::string> names;
    for (const auto& row : result.stages) names.push_back(row.stage);
    EXPECT_EQ(names, (std::vector<std::string>{"clouds", "extract", "align", "mesh"}));
    EXPECT_EQ(begun, (std::vector<std::string>{"clouds", "align", "mesh"}));
    EXPECT_EQ(saved, (std::vector<std::string>{"views", "align"}));
    EXPECT_FALSE(result.report.contains("fill"));
}

// beside_mesh runs once, while the mesh stage runs (the result's input is there, its mesh not
// yet), and the mesh does not depend on it.
TEST(Reconstruct, BesideMeshSeesTheInputBeforeTheMeshAndChangesNothing) {
    rgbd::pipeline::ReconstructOptions options;
    options.skip = {"distance", "upsample", "density", "fill"};
    options.mesh.watertight = false;
    const auto frames = rgbd::pipeline::frameset_frames(capture(), 0);
    const auto plain = rgbd::pipeline::reconstruct(capture(), frames, options);
    int calls = 0;
    std::size_t input_points = 0, mesh_faces_then = 1;
    rgbd::pipeline::ReconstructHooks hooks;
    hooks.beside_mesh = [&](const rgbd::pipeline::ReconstructResult& r) {
        ++calls;
        input_points = r.input.vertices.size();
        mesh_faces_then = r.mesh.number_of_faces();
    };
    const auto result = rgbd::pipeline::reconstruct(capture(), frames, options, hooks);
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(input_points, result.input.vertices.size());
    EXPECT_GT(input_points, 1000u);
    EXPECT_EQ(mesh_faces_then, 0u) << "the hook runs before the mesh is stored";
    ASSERT_EQ(result.mesh.number_of_vertices(), plain.mesh.number_of_vertices());
    ASSERT_EQ(result.mesh.number_of_faces(), plain.mesh.number_of_faces());
    auto a = plain.mesh.vertices().begin();
    for (auto v : result.mesh.vertices()) EXPECT_EQ(result.mesh.point(v), plain.mesh.point(*a++));
}

TEST(Reconstruct, TheFirstBrokenViewIsReportedWhateverTheThreads) {
    // Views are loaded in parallel: with two truncated depth images (cam2 and cam5), the error
    // always names the first view's file.
    namespace fs = std::filesystem;
    const fs::path dir = rgbd::test::scratch_dir("rgbd_pipeline_broken");
    fs::remove_all(dir);
    fs::copy(capture().root, dir, fs::copy_options::recursive);
    for (const char* cam : {"cam2", "cam5"})
        for (const auto& f : fs::directory_iterator(dir / cam / "depth"))
            fs::resize_file(f.path(), 40);
    const rgbd::io::Capture broken = rgbd::io::open_capture(dir);
    const auto frames = rgbd::pipeline::frameset_frames(broken, 0);
    for (int run = 0; run < 4; ++run) {
        try {
            rgbd::pipeline::reconstruct(broken, frames, rgbd::pipeline::ReconstructOptions{});
            FAIL() << "a truncated depth image was read";
        } catch (const rgbd::Error& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find("cam2"), std::string::npos) << what;
            EXPECT_EQ(what.find("cam5"), std::string::npos) << what;
        }
    }
    fs::remove_all(dir);
}

TEST(Reconstruct, BadOptionsAndFrameSetsAreInputErrors) {
    rgbd::pipeline::ReconstructOptions options;
    options.skip = {"mesh"};
    EXPECT_THROW(options.check(), rgbd::InputError);
    EXPECT_THROW(rgbd::pipeline::frameset_frames(capture(), 1), rgbd::InputError);
}

}  // namespace
