// The whole method as one call (pipeline::reconstruct, what rgbd-reconstruct runs), then the
// mesh against the true surface (F-score, completeness), and the per-stage report.
// Usage: reconstruct_and_evaluate [CAPTURE_DIR REFERENCE_MESH]  (default: a synthetic sphere)
#include <filesystem>
#include <iostream>

#include "example_data.hpp"
#include "io/mesh_io.hpp"
#include "pipeline/reconstruct.hpp"
#include "pipeline/stages.hpp"

int main(int argc, char** argv) try {
    const bool given = argc > 2;
    const std::filesystem::path root =
        given ? std::filesystem::path(argv[1])
              : examples::make_capture(std::filesystem::temp_directory_path() / "rgbd_ex_mesh", 8,
                                       /*above_and_below=*/true);
    const rgbd::io::Capture capture = rgbd::io::open_capture(root);
    rgbd::pipeline::ReconstructOptions options;  // every stage with its defaults, watertight
    const rgbd::pipeline::ReconstructResult result =
        rgbd::pipeline::reconstruct(capture, rgbd::pipeline::frameset_frames(capture, 0), options);
    for (const auto& stage : result.stages)
        std::cout << stage.stage << ": " << stage.time_s << " s, points " << stage.points_in
                  << " -> " << stage.points_out << "\n";
    rgbd::pipeline::LoadedResult mesh;
    mesh.mesh = result.mesh;
    const rgbd::Mesh reference =
        given ? rgbd::io::read_mesh(argv[2]) : examples::reference_sphere();
    const rgbd::Report metrics = rgbd::pipeline::evaluate_surface(mesh, reference, {});
    std::cout << result.mesh.number_of_faces() << " faces; F-score@5mm " << metrics["fscore_5mm"]
              << ", completeness " << metrics["completeness_mean_m"].get<double>() * 1000
              << " mm\n";
    return metrics["fscore_5mm"].get<double>() > 0.9 ? 0 : 1;
} catch (const std::exception& e) {
    std::cerr << "reconstruct_and_evaluate: " << e.what() << "\n";
    return 1;
}
