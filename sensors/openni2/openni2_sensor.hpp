// OpenNI2 devices (Kinect v1 through the freenect driver, Asus Xtion, PrimeSense, Orbbec) as a
// Sensor: depth in millimetres (PIXEL_FORMAT_DEPTH_1_MM) and RGB888 colour, registered
// depth-to-colour off; intrinsics from the streams' fields of view. Built only with
// RGBD_WITH_OPENNI2 (libopenni2-dev found at configure time).
#pragma once

#include <memory>
#include <string>

#include "sensors/sensor.hpp"

namespace rgbd::sensors {

struct OpenNi2Options {
    std::string uri;               ///< device URI; empty = the first device
    std::string id = "openni2-0";  ///< sensor id
    std::int64_t max_frames = 0;   ///< 0 = no limit
    bool color = true;             ///< open the colour stream too
};

class OpenNi2Sensor final : public Sensor {
public:
    /// Opens the device; throws IoError with OpenNI's message when there is none.
    explicit OpenNi2Sensor(const OpenNi2Options& options);
    ~OpenNi2Sensor() override;
    const io::SensorSpec& spec() const override { return spec_; }
    double frame_rate_hz() const override { return rate_hz_; }
    bool next(SensorFrame& frame) override;

private:
    struct Device;
    std::unique_ptr<Device> device_;
    OpenNi2Options options_;
    io::SensorSpec spec_;
    double rate_hz_ = 30;
    std::int64_t produced_ = 0;
};

}  // namespace rgbd::sensors
