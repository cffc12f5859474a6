#include "pipeline/texture_views.hpp"

#include <opencv2/imgproc.hpp>

#include "toolkit/error.hpp"

namespace rgbd::pipeline {

std::vector<std::pair<std::string, std::size_t>> frames_of_views(
    const io::Capture& capture, const std::vector<PointCloud>& views) {
    const std::string root = capture.root.string();
    std::vector<std::pair<std::string, std::size_t>> frames;
    for (const auto& v : views) {
        const auto it = capture.frames.find(v.view.sensor);
        if (it == capture.frames.end() || it->second.empty()) continue;
        std::size_t position = 0;
        if (v.view.frame_index) {
            const auto found = capture.find_frame(v.view.sensor, *v.view.frame_index);
            RGBD_CHECK(found.has_value(), root + ": view " + std::to_string(v.view.id) +
                                              " names frame " +
                                              std::to_string(*v.view.frame_index) + " of sensor " +
                                              v.view.sensor + ", which the capture does not have");
            position = *found;
        }
        frames.emplace_back(v.view.sensor, position);
    }
    RGBD_CHECK(!frames.empty(),
               root + ": no view of the stream comes from a sensor of this capture");
    return frames;
}

std::vector<texture::TextureView> load_texture_views(
    const io::Capture& capture, const std::vector<std::pair<std::string, std::size_t>>& frames,
    const std::vector<PointCloud>* aligned) {
    const std::string root = capture.root.string();
    RGBD_CHECK(!frames.empty(), root + ": no frames selected");
    std::vector<texture::TextureView> out;
    for (const auto& [id, position] : frames) {
        RgbdFrame frame = io::load_frame(capture, id, position);
        const std::string name = id + " frame " + std::to_string(frame.frame_index);
        RGBD_CHECK(!frame.color.empty(),
                   root + ": " + name + " has no colour image (texturing needs them)");
        std::optional<Pose> world_from_sensor;
        if (frame.has_pose) world_from_sensor = frame.world_from_sensor;
        if (aligned)
            for (const auto& v : *aligned)
                if (v.view.sensor == id && v.view.world_from_sensor &&
                    (!v.view.frame_index || *v.view.frame_index == frame.frame_index)) {
                    world_from_sensor = *v.view.world_from_sensor;
                    break;
                }
        RGBD_CHECK(world_from_sensor.has_value(),
                   root + ": " + name + " has no pose (rig.json world_from_depth or --views)");
        texture::TextureView view;
        view.name = name;
        view.intrinsics = frame.color_intrinsics;
        view.world_from_camera = *world_from_sensor * frame.color_from_depth.inverse();
        if (frame.color_intrinsics.distortion.is_none()) {
            view.image = frame.color;
        } else {
            // Undistorted onto the same pinhole camera (the rasteriser is exact for pinholes).
            const auto& k = frame.color_intrinsics;
            cv::Mat map_x(k.height, k.width, CV_32FC1), map_y(k.height, k.width, CV_32FC1);
            for (int r = 0; r < k.height; ++r)
                for (int c = 0; c < k.width; ++c) {
                    const Eigen::Vector2d xy =
                        k.distortion.distort({(c - k.cx) / k.fx, (r - k.cy) / k.fy});
                    map_x.at<float>(r, c) = static_cast<float>(k.fx * xy.x() + k.cx);
                    map_y.at<float>(r, c) = static_cast<float>(k.fy * xy.y() + k.cy);
                }
            cv::remap(frame.color, view.image, map_x, map_y, cv::INTER_LINEAR,
                      cv::BORDER_REPLICATE);
            view.intrinsics.distortion = Distortion{};
        }
        out.push_back(std::move(view));
    }
    return out;
}

}  // namespace rgbd::pipeline
