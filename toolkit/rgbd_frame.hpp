// RgbdFrame: one organised depth + colour frame of one sensor (docs/architecture.md, the data
// model). Dense data lives only here; point clouds keep `pixel` back-references into it.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

#include "toolkit/camera.hpp"
#include "toolkit/pose.hpp"

namespace rgbd {

struct RgbdFrame {
    cv::Mat depth;       ///< CV_32FC1, metres, NaN = invalid
    cv::Mat color;       ///< CV_8UC3, BGR; may be empty (no colour)
    cv::Mat confidence;  ///< optional CV_32FC1 in [0, 1]
    PinholeIntrinsics depth_intrinsics;
    PinholeIntrinsics color_intrinsics;
    Pose color_from_depth = Pose::Identity();   ///< extrinsics depth camera -> colour camera
    Pose world_from_sensor = Pose::Identity();  ///< pose of the depth camera
    bool has_pose = false;                      ///< world_from_sensor is known
    std::string sensor_id;
    std::int64_t frame_index = 0;
    std::int64_t timestamp_ns = 0;  ///< hub time
    std::string source;             ///< path of the depth image, for provenance
    float range_min_m = 0.0f;       ///< valid depth range of the sensor (0 = unknown)
    float range_max_m = 0.0f;
    std::string noise_model;   ///< the sensor's noise model name (rig noise.model) or empty
    std::string sensor_model;  ///< the sensor's model ("kinect_v2", "sr300", ...) or empty
    cv::Mat mask;              ///< optional CV_8UC1 object mask on the depth grid, 0 = background
};

}  // namespace rgbd
