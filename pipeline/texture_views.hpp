// The colour images of a capture as texture views (rgbd-texture, rgbd-reconstruct -o
// model.obj|glb, rgbd-eval --colour; docs/algorithms.md "Texturing"): each selected frame's
// colour image, undistorted to a pinhole camera with the same intrinsics, and the pose of its
// colour camera, world_from_colour = world_from_sensor * color_from_depth^-1, with
// world_from_sensor from the capture (rig.json, frames.csv) or, when given, from aligned views
// (rgbd-align's refined poses, matched by sensor id and frame index).
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/texture/view_selection.hpp"
#include "io/capture_folder.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::pipeline {

/// The frames of `capture` that `views` were made from (view.sensor, view.frame_index; a view
/// without a frame index takes its sensor's first frame). Views of sensors the capture does not
/// have (rgbd-fill's added points) are skipped. Throws InputError naming the capture when a
/// view's frame is not in the capture or no view matches.
std::vector<std::pair<std::string, std::size_t>> frames_of_views(
    const io::Capture& capture, const std::vector<PointCloud>& views);

/// Loads the colour images of `frames` as texture views; `aligned` (may be null) overrides each
/// frame's world_from_sensor by the matching view's. Throws InputError naming the capture and
/// frame when a frame has no colour image, no pose, or an image not of the rig's colour size;
/// IoError for an unreadable image.
std::vector<texture::TextureView> load_texture_views(
    const io::Capture& capture, const std::vector<std::pair<std::string, std::size_t>>& frames,
    const std::vector<PointCloud>* aligned = nullptr);

}  // namespace rgbd::pipeline
