// Opens a sensor from a "kind:argument" string (the --sensor option of rgbd-node):
//   playback:FOLDER[#ID]     one sensor of a capture folder (or TUM sequence) replayed in real
//                            time; FOLDER may also be CAPTURE/ID (docs/formats.md)
//   synthetic:[ID]           the synthetic sensor (sensors/synthetic/synthetic_sensor.hpp)
//   openni2:[URI]            an OpenNI2 device (only when built with RGBD_WITH_OPENNI2)
#pragma once

#include <memory>
#include <string>

#include "sensors/playback/playback_sensor.hpp"
#include "sensors/sensor.hpp"

namespace rgbd::sensors {

struct OpenOptions {
    PlaybackOptions playback;     ///< playback: timing, loop, frame limit
    std::int64_t max_frames = 0;  ///< every kind: stop after this many frames (0 = no limit)
    double rate_hz = 30.0;        ///< synthetic: frame rate
};

/// Throws InputError naming the string for an unknown kind or a bad argument.
std::unique_ptr<Sensor> open_sensor(const std::string& what, const OpenOptions& options = {});

}  // namespace rgbd::sensors
