// Cleans one view with the adaptive distance-based filter (docs/algorithms.md): flying pixels
// are added to a synthetic frame, and the filter must remove most of them.
// Usage: clean_view  (no arguments: the view comes from a synthetic capture it writes)
#include <filesystem>
#include <iostream>
#include <random>

#include "algorithms/denoise/distance_outliers.hpp"
#include "example_data.hpp"
#include "pipeline/stages.hpp"

/// Points of the view (world frame) farther than 5 mm from the sphere.
std::size_t off_surface(const rgbd::PointCloud& view) {
    std::size_t n = 0;
    for (const auto& p : view.points.points()) {
        const Eigen::Vector3d w =
            *view.view.world_from_sensor * Eigen::Vector3d(p.x(), p.y(), p.z());
        n += std::abs(w.norm() - examples::kRadius) > 0.005;
    }
    return n;
}

int main() try {
    const auto root =
        examples::make_capture(std::filesystem::temp_directory_path() / "rgbd_ex_clean");
    const rgbd::io::Capture capture = rgbd::io::open_capture(root);
    rgbd::RgbdFrame frame = rgbd::io::load_frame(capture, "cam0", 0);
    // 300 flying pixels: depths between the sphere's rim and nowhere, as at real silhouettes.
    std::mt19937 rng(7);
    for (int added = 0; added < 300;) {
        const int u = std::uniform_int_distribution<int>(0, frame.depth.cols - 1)(rng);
        const int v = std::uniform_int_distribution<int>(0, frame.depth.rows - 1)(rng);
        float& d = frame.depth.at<float>(v, u);
        if (std::isnan(d) || d <= 0) continue;
        d += std::uniform_real_distribution<float>(0.03f, 0.3f)(rng);
        ++added;
    }
    rgbd::Report report;
    rgbd::PointCloud view = rgbd::pipeline::view_from_frame(frame, 0, {}, std::nullopt, {}, report);
    const std::size_t before = view.size(), bad_before = off_surface(view);
    rgbd::denoise::DistanceOptions options;  // Kinect v2 noise model, the paper's defaults
    const rgbd::Report clean = rgbd::denoise::remove_distance_outliers(view, options);
    const std::size_t bad_after = off_surface(view);
    std::cout << "points " << before << " -> " << view.size() << "; off the surface (> 5 mm) "
              << bad_before << " -> " << bad_after << "; flying " << clean["flying"] << "\n";
    return bad_after * 4 < bad_before ? 0 : 1;  // at least three quarters removed
} catch (const std::exception& e) {
    std::cerr << "clean_view: " << e.what() << "\n";
    return 1;
}
