// Detects the holes of a set of aligned views and fills them (docs/algorithms.md, hole
// detection and filling): the ring of cameras above a sphere never sees its underside.
// Usage: fill_holes  (no arguments: the views come from a synthetic capture it writes)
#include <filesystem>
#include <iostream>

#include "example_data.hpp"
#include "pipeline/fill_stage.hpp"
#include "pipeline/reconstruct.hpp"
#include "pipeline/stages.hpp"

int main() try {
    const auto root =
        examples::make_capture(std::filesystem::temp_directory_path() / "rgbd_ex_fill");
    const rgbd::io::Capture capture = rgbd::io::open_capture(root);
    const auto frames = rgbd::pipeline::frameset_frames(capture, 0);
    const auto centre = rgbd::pipeline::object_centre(capture, frames);
    std::vector<rgbd::PointCloud> views;
    for (const auto& [sensor, position] : frames) {
        rgbd::Report report;
        views.push_back(rgbd::pipeline::load_view(
            capture, sensor, position, static_cast<int>(views.size()), {}, centre, {}, report));
    }
    // Alignment refines the rig's poses and brings the views into the world frame.
    rgbd::pipeline::align_stage(views, {});
    std::vector<rgbd::PointCloud*> pointers;
    for (auto& view : views) pointers.push_back(&view);
    rgbd::Report report;
    const auto added = rgbd::pipeline::fill_stage(pointers, {}, report);
    std::cout << report["loop_list"].size() << " hole loops; " << (added ? added->size() : 0)
              << " points added\n";
    if (!added) return 1;
    // The added points lie near the sphere they complete.
    double worst = 0;
    for (const auto& p : added->points.points())
        worst = std::max(worst, std::abs(std::hypot(p.x(), p.y(), p.z()) - examples::kRadius));
    std::cout << "farthest added point from the sphere: " << worst * 1000 << " mm\n";
    return worst < 0.03 ? 0 : 1;
} catch (const std::exception& e) {
    std::cerr << "fill_holes: " << e.what() << "\n";
    return 1;
}
