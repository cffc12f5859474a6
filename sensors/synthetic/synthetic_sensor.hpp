// The synthetic sensor: a Kinect v2 like depth camera (512x424, f = 365.5) looking at a
// sphere that swings left and right in front of a textured wall, rendered analytically per
// frame with deterministic depth noise and 1 mm quantisation, and a colour camera of a chosen
// (smaller than Kinect's) resolution. Needs no files: for network tests and demos of
// rgbd-node. For full synthetic captures with ground truth see validation/synth (rgbd-synth).
#pragma once

#include <cstdint>
#include <string>

#include "sensors/sensor.hpp"

namespace rgbd::sensors {

struct SyntheticOptions {
    std::string id = "synthetic-0";  ///< sensor id
    double rate_hz = 30.0;           ///< frame rate
    std::int64_t max_frames = 0;     ///< 0 = no limit
    int color_width = 640;           ///< colour resolution (Kinect v2 field of view)
    int color_height = 360;
    double noise_mm = 1.5;  ///< axial noise amplitude (uniform, deterministic per pixel/frame)
    bool realtime = true;   ///< wait for each frame's instant
};

class SyntheticSensor final : public Sensor {
public:
    explicit SyntheticSensor(const SyntheticOptions& options);
    const io::SensorSpec& spec() const override { return spec_; }
    double frame_rate_hz() const override { return options_.rate_hz; }
    bool next(SensorFrame& frame) override;
    /// The first frame is captured at `monotonic_ns`, the others one period apart.
    bool start_at(std::int64_t monotonic_ns) override;

    /// Renders frame `index` (deterministic) into depth (CV_16UC1 mm) and colour (BGR).
    void render(std::int64_t index, cv::Mat& depth, cv::Mat& color) const;

private:
    SyntheticOptions options_;
    io::SensorSpec spec_;
    std::int64_t produced_ = 0;
    std::int64_t start_ns_ = 0;
    bool start_set_ = false;
};

}  // namespace rgbd::sensors
