// The observations of a capture, for judging a reconstruction of a real capture without ground
// truth (rgbd-eval --observed): every selected frame back-projected with the capture's own
// calibration (depth_to_cloud: intrinsics, distortion, depth window, masks), then cut to the
// observed subject (evaluation::observed_subject), by the synthetic truth labels
// gt/<sensor>/segment/NNNNNN.png when the capture has them. docs/method.md (evaluation).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/evaluation/observed.hpp"
#include "algorithms/frames/depth_to_cloud.hpp"
#include "io/capture_folder.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/report.hpp"

namespace rgbd::pipeline {

/// The observed subject of a capture.
struct Observations {
    /// One view per selected frame, in the sensor frame with its world_from_sensor pose,
    /// keeping only the subject points (possibly none).
    std::vector<PointCloud> views;
    /// observed_subject's report plus "views" (count), "labels" (the label folder used, or
    /// null) and per view {sensor, frame_index, points}.
    Report report;

    /// Every point in the world frame, view after view.
    std::vector<Eigen::Vector3d> world_points() const;
};

/// Where rgbd-synth puts the subject labels of a frame: gt/<sensor>/segment/ with the depth
/// image's file name (uint8: 1 subject, 2 support, 3 background; evaluation::kLabelSubject).
std::filesystem::path segment_label_file(const io::Capture& capture, const std::string& sensor_id,
                                         std::size_t position);

/// Where rgbd-synth puts the noise labels of a frame: gt/<sensor>/labels/ with the depth image's
/// file name (uint8: 0 no return, 1 surface, 2 flying pixel, 3 outlier, 4 dropout, 5 shadow).
std::filesystem::path noise_label_file(const io::Capture& capture, const std::string& sensor_id,
                                       std::size_t position);

/// The noise label of a pixel whose depth measures a surface (docs/formats.md).
inline constexpr std::uint8_t kNoiseLabelSurface = 1;

/// Loads `frames` of `capture` as views (io::load_frame, depth_to_cloud with `cloud_options`,
/// no crop) and keeps the observed subject: the label images when the first frame has one
/// (then every frame must; where a frame also has noise labels, its flying pixels and random
/// outliers are no observation of the subject: report "noise_excluded" counts them), else the
/// cylinder around where the sensors' axes converge (object_centre) minus the ground plane
/// (evaluation::observed_subject), which is not looked for when every frame's object mask was
/// applied (the masks left no ground). With `poses` (sensor id -> world_from_depth, e.g. a
/// synthetic capture's truth), the views are placed with those instead of the capture's
/// calibration; report: poses "given" or "capture".
/// @throws InputError naming the capture when no frame is selected, a frame has no pose
///         (rig.json world_from_depth or frames.csv pose columns), a label file is missing
///         while others exist, or no observed point is left; IoError for unreadable files.
Observations load_observations(const io::Capture& capture,
                               const std::vector<std::pair<std::string, std::size_t>>& frames,
                               const frames::CloudOptions& cloud_options,
                               const evaluation::SubjectOptions& subject,
                               const std::map<std::string, Pose>* poses = nullptr);

}  // namespace rgbd::pipeline
