// The Sensor interface (DESIGN.md §5, STYLE.md §1): anything that produces RGB-D frames at a
// rate: a recording played back as a virtual sensor, the synthetic sensor, a device. A sensor
// only produces frames; sending and recording them is the job of rgbd-node / rgbd-capture.
// See also: sensors/playback/playback_sensor.hpp, sensors/synthetic/synthetic_sensor.hpp,
// sensors/registry.hpp (open a sensor from a "kind:argument" string).
#pragma once

#include <chrono>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "io/capture_folder.hpp"

namespace rgbd::sensors {

/// The machine's monotonic clock in nanoseconds (std::chrono::steady_clock, which is
/// CLOCK_MONOTONIC on Linux and therefore shared by every process of one machine).
inline std::int64_t monotonic_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

/// One frame as a sensor delivers it. Buffers are reused between frames by the sensor when
/// the caller passes the same object again (no allocation per frame once warmed up).
struct SensorFrame {
    std::int64_t index = 0;       ///< the sensor's frame counter, from 0
    std::int64_t capture_ns = 0;  ///< capture instant on the machine's monotonic clock
    std::int64_t device_ns = 0;   ///< the device's own time stamp (its clock, its epoch)
    cv::Mat depth;                ///< CV_16UC1 in the spec's depth_scale units, 0 = invalid
    cv::Mat color;                ///< CV_8UC3 BGR, or empty when color_jpeg holds the colour
    std::vector<std::uint8_t> color_jpeg;  ///< colour already JPEG-encoded (may be empty)
    std::int64_t source_position = -1;     ///< playback: position in the recording, else -1
};

class Sensor {
public:
    virtual ~Sensor() = default;
    /// Intrinsics, extrinsics, depth scale: the sensor's entry of a rig.json.
    virtual const io::SensorSpec& spec() const = 0;
    /// Nominal frame rate in Hz.
    virtual double frame_rate_hz() const = 0;
    /// Waits until the next frame is captured and fills `frame`. Returns false when the sensor
    /// has no more frames (end of a recording, frame limit). Throws rgbd::Error on failure.
    virtual bool next(SensorFrame& frame) = 0;
    /// Asks the sensor to capture its first frame at `monotonic_ns` (this machine's monotonic
    /// clock) and every later one on that instant's frame grid, so that the sensors of a rig
    /// started by the hub on one common instant capture together (the software trigger of
    /// LiveScan3D). Call before the first next(). Returns false when the sensor cannot be
    /// told (a free-running device): it then keeps its own timing.
    virtual bool start_at(std::int64_t monotonic_ns) {
        (void)monotonic_ns;
        return false;
    }
};

}  // namespace rgbd::sensors
