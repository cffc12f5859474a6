// Reads a capture folder and turns one frame of each sensor into a coloured point view.
// Usage: read_capture [CAPTURE_DIR]  (default: a synthetic ring capture it writes itself)
#include <filesystem>
#include <iostream>

#include "example_data.hpp"
#include "io/capture_folder.hpp"
#include "pipeline/reconstruct.hpp"
#include "pipeline/stages.hpp"

int main(int argc, char** argv) try {
    const std::filesystem::path root =
        argc > 1 ? std::filesystem::path(argv[1])
                 : examples::make_capture(std::filesystem::temp_directory_path() / "rgbd_ex_read");
    const rgbd::io::Capture capture = rgbd::io::open_capture(root);
    std::cout << root.string() << ": layout " << capture.layout << ", "
              << capture.rig.sensors.size() << " sensors, " << capture.framesets.size()
              << " frame sets\n";
    // The frames of frame set 0, and the point the sensors look at (for the object crop).
    const auto frames = rgbd::pipeline::frameset_frames(capture, 0);
    const auto centre = rgbd::pipeline::object_centre(capture, frames);
    std::size_t total = 0;
    for (const auto& [sensor, position] : frames) {
        const rgbd::RgbdFrame frame = rgbd::io::load_frame(capture, sensor, position);
        rgbd::Report report;
        const rgbd::PointCloud view =
            rgbd::pipeline::view_from_frame(frame, static_cast<int>(total), {}, centre, {}, report);
        std::cout << "  " << sensor << ": depth " << frame.depth.cols << "x" << frame.depth.rows
                  << ", " << view.size() << " points in the view\n";
        if (view.empty()) return 1;
        total += view.size();
    }
    std::cout << total << " points in " << frames.size() << " views\n";
    return 0;
} catch (const std::exception& e) {
    std::cerr << "read_capture: " << e.what() << "\n";
    return 1;
}
