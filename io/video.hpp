// The 3D video folder (docs/formats.md "3D video folder"): what rgbd-capture --video writes and
// rgbd-view plays. DIR holds
//   video.json           the rig, the frame rate, counters, and per fused frame set its time,
//                        spread, sensors, points, bytes, hub processing ms and end-to-end latency;
//   rig.json             the rig the video was captured with;
//   frames/NNNNNN.drc    one Draco-compressed coloured point cloud per fused frame set (world
//                        frame, metres), each self-describing (its set, time and spread in the
//                        Draco geometry metadata).
// Frames are written atomically as they come and video.json is rewritten atomically at most
// every `index_interval_s` (1 s) and at the end, so a capture cut short keeps every frame before
// the cut: read_video() lists frame files that the index does not name yet from their metadata.
// Draco (Debian libdraco-dev, Google's point cloud codec): positions quantised on an explicit
// grid of `position_quantum_m`, colour as 8-bit RGB (optionally reduced to `color_bits`).
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "io/capture_folder.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::io {

/// A coloured point cloud in flat arrays (what a video frame holds).
struct ColoredPoints {
    std::vector<Eigen::Vector3f> xyz;  ///< metres, world frame
    std::vector<Rgb> rgb;              ///< same size as xyz, or empty (no colour)
    std::size_t size() const { return xyz.size(); }
};

/// PointCloud (world frame) <-> flat arrays.
ColoredPoints to_colored_points(const PointCloud& cloud);
PointCloud to_point_cloud(const ColoredPoints& points);

/// Draco settings of a video.
struct DracoSettings {
    /// Position grid in metres (explicit quantisation: bits chosen from the cloud's extent).
    double position_quantum_m = 0.002;
    /// Bits kept per colour channel (1..8; the rest are dropped and restored as the centre of
    /// the dropped range when decoding).
    int color_bits = 6;
    /// Draco encoding speed 0 (smallest) .. 10 (fastest).
    int speed = 10;
    /// Throws InputError for out-of-range values.
    void check() const;
    nlohmann::json to_json() const;
};

/// Metadata stored inside every frame file.
struct FrameMeta {
    std::int64_t frame = -1;  ///< number in the video, from 0
    std::int64_t set = -1;    ///< frame set number of the capture
    std::int64_t time_ns = 0;
    std::int64_t spread_ns = 0;
};

/// Encodes points (positions + colour) into a Draco buffer with `meta` as geometry metadata.
std::vector<std::uint8_t> encode_draco(const ColoredPoints& points, const DracoSettings& settings,
                                       const FrameMeta& meta);
/// Decodes a Draco point cloud made by encode_draco (or any Draco point cloud with positions,
/// optionally colour). Throws InputError naming `what` for anything that does not decode.
ColoredPoints decode_draco(const std::uint8_t* data, std::size_t size, const std::string& what,
                           FrameMeta* meta = nullptr);

/// One fused frame set in video.json.
struct VideoFrame {
    std::int64_t frame = 0;    ///< number in the video (file frames/NNNNNN.drc)
    std::int64_t set = 0;      ///< frame set number of the capture
    std::int64_t time_ns = 0;  ///< the set's capture instant, hub time
    std::int64_t spread_ns = 0;
    int sensors = 0;  ///< views fused (fewer than the rig's sensors: a thinned set)
    std::size_t points = 0;
    std::size_t bytes = 0;  ///< size of the .drc file
    double hub_ms = 0;      ///< hub processing of this set (fusion + encoding), wall ms
    double latency_ms = 0;  ///< capture instant -> frame written, ms
    std::string file;       ///< relative to DIR
    std::string problem;    ///< read_video: why the frame cannot be played ("" = fine)
    bool indexed = true;    ///< read_video: named by video.json (false: found on disk only)
};

/// The video as read back.
struct VideoInfo {
    std::filesystem::path root;
    nlohmann::json header;  ///< video.json without "frames"
    double frame_rate_hz = 0;
    std::vector<VideoFrame> frames;  ///< in frame order
    bool complete = false;           ///< video.json says the writer finished
};

/// frames/NNNNNN.drc of frame `frame`.
std::string video_frame_file(std::int64_t frame);

/// Reads video.json (InputError/IoError naming the file) and checks every frame file: a
/// missing, truncated or stale one (size differs from the index, or a header that is not
/// Draco) gets a `problem`; frame files the index does not name yet are added from their
/// metadata (indexed = false).
VideoInfo read_video(const std::filesystem::path& root);
/// Decodes frame `frame` of a video (InputError naming the file when it does not decode).
ColoredPoints read_video_frame(const VideoInfo& video, std::int64_t frame,
                               FrameMeta* meta = nullptr);

/// Writes a video folder as it goes (not thread-safe: one writer thread).
class VideoWriter {
public:
    /// Creates `root` (must not exist or be empty), frames/, rig.json and a first video.json.
    /// `header` is merged into video.json (placement, voxel size, options...).
    VideoWriter(const std::filesystem::path& root, const Rig& rig, double frame_rate_hz,
                const DracoSettings& draco, const nlohmann::json& header,
                double index_interval_s = 1.0);
    ~VideoWriter();
    VideoWriter(const VideoWriter&) = delete;
    VideoWriter& operator=(const VideoWriter&) = delete;

    /// Encodes and writes one frame atomically; fills frame, file, points, bytes of `info`
    /// (the caller fills the rest and may set hub_ms / latency_ms after this returns through
    /// update_last()). Throws IoError naming the file (e.g. disk full): the frame is not
    /// listed and the folder stays readable.
    const VideoFrame& add(const ColoredPoints& points, VideoFrame info);
    /// Sets the last frame's hub_ms and latency_ms (known only once it is written).
    void update_last(double hub_ms, double latency_ms);
    /// Rewrites video.json now (also done by add() every index_interval_s).
    void write_index();
    /// Final video.json: counters and stop reason, "complete": true. Throws IoError.
    void finish(const nlohmann::json& counters, const std::string& stop_reason);

    std::int64_t frames() const { return static_cast<std::int64_t>(frames_.size()); }
    std::size_t bytes() const { return bytes_; }
    const std::filesystem::path& root() const { return root_; }

private:
    std::filesystem::path root_;
    nlohmann::json header_;
    DracoSettings draco_;
    std::vector<VideoFrame> frames_;
    std::size_t bytes_ = 0;
    double index_interval_s_;
    std::chrono::steady_clock::time_point last_index_;
};

}  // namespace rgbd::io
