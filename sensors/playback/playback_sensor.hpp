// Playback of a recording as a virtual sensor (DESIGN.md §5): one sensor of a capture folder
// v1 (or of any layout io::open_capture reads, e.g. TUM RGB-D) replayed at its recorded rate.
// Depth is delivered exactly as stored (16-bit, no conversion); JPEG colour is delivered as the
// file's bytes (no decode / re-encode), other colour formats decoded to BGR.
// See also: sensors/sensor.hpp, io/capture_folder.hpp.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "sensors/sensor.hpp"

namespace rgbd::sensors {

struct PlaybackOptions {
    /// Replay in real time (wait for each frame's instant); false = as fast as asked.
    bool realtime = true;
    /// Start again at the first frame after the last one (indices and times keep growing).
    bool loop = false;
    /// Real time only: put frame instants on a grid of the monotonic clock whose period is the
    /// recording's loop length, keeping the recorded phase between sensors. Several playback
    /// sensors of one capture on one machine then capture "in phase", like a hardware-triggered
    /// rig, wherever and whenever each was started (a restarted one rejoins the same grid).
    bool align_to_clock = true;
    /// Frame rate used when the recording has a single frame per sensor (Hz).
    double default_rate_hz = 30.0;
    /// Stop after this many frames (0 = no limit; without loop the recording's end stops).
    std::int64_t max_frames = 0;
    /// Read every frame into memory when opening (steady timing, no allocation per frame).
    bool preload = true;
    /// Deliver JPEG colour decoded (BGR in SensorFrame::color) like a device does, instead of
    /// the file's bytes: for a node that makes views itself (rgbd-node --views). With preload
    /// the decoding is done once when opening.
    bool decode_color = false;
};

class PlaybackSensor final : public Sensor {
public:
    /// Opens sensor `sensor_id` of the capture at `root` (empty id: the capture must have
    /// exactly one sensor). Throws InputError/IoError naming the file or the id.
    PlaybackSensor(const std::filesystem::path& root, const std::string& sensor_id,
                   const PlaybackOptions& options = {});

    const io::SensorSpec& spec() const override { return spec_; }
    double frame_rate_hz() const override { return 1e9 / static_cast<double>(period_ns_); }
    bool next(SensorFrame& frame) override;
    /// The first frame is delivered at `monotonic_ns` (real time), the others keep their
    /// recorded distance from it; overrides align_to_clock.
    bool start_at(std::int64_t monotonic_ns) override;

    /// Number of frames in the recording of this sensor.
    std::size_t recording_size() const { return records_.size(); }
    /// Loop length in ns (the recording's span rounded up to whole frame periods).
    std::int64_t loop_ns() const { return loop_ns_; }

private:
    struct Stored {
        cv::Mat depth;
        cv::Mat color;
        std::vector<std::uint8_t> color_jpeg;
    };
    void load(std::size_t position, Stored& out) const;

    io::Capture capture_;
    io::SensorSpec spec_;
    PlaybackOptions options_;
    std::vector<io::FrameRecord> records_;
    std::vector<std::int64_t> offset_ns_;  ///< per position: hub time - capture start
    std::vector<Stored> frames_;           ///< preloaded frames (empty without preload)
    Stored scratch_;                       ///< on-demand loading buffer
    std::int64_t period_ns_ = 33333333;
    std::int64_t loop_ns_ = 33333333;
    std::int64_t origin_ns_ = 0;  ///< monotonic instant of loop 0, position offset 0
    std::int64_t produced_ = 0;
    bool started_ = false;
    std::optional<std::int64_t> start_ns_;  ///< start_at's instant
};

}  // namespace rgbd::sensors
