// rgbd-capture --video: the live network fused into a 3D video (issue 20, docs/formats.md "3D
// video folder"). The hub hands every formed frame set to VideoStream; a thread of its own
// fuses the newest one (pipeline/video_fusion.hpp: per-view work for raw frames here, node
// views as they came), encodes it with Draco and appends it to the video folder (io/video.hpp),
// and offers it to the live web page (--serve, cli/view_server.hpp). A fusion slower than the
// sensors gets the newest set each time it is ready: the sets in between are skipped and
// counted, never queued, so latency stays bounded. Every formed set ends up counted as fused,
// skipped or empty (no view), and a set missing views (a node that dropped out or lags) is
// fused thinned and counted. A write error (full disk) ends the video with what was written.
#pragma once

#include <tbb/task_arena.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cli/capture_live.hpp"
#include "cli/newest_worker.hpp"
#include "io/video.hpp"
#include "pipeline/video_fusion.hpp"
#include "toolkit/report.hpp"

namespace rgbd::cli {

class Context;

struct VideoOptions {
    std::string dir;            ///< the video folder
    bool fuse_on_nodes = true;  ///< the nodes send views (else frames, fused here)
    pipeline::VideoFusionOptions fusion;
    io::DracoSettings draco;
    double frame_rate_hz = 30.0;  ///< written to video.json
};

/// A fused frame for a live viewer.
struct FusedFrame {
    std::int64_t frame = -1;
    io::VideoFrame info;
    io::ColoredPoints points;
};

class VideoStream {
public:
    /// Creates the video folder (IoError naming it) and starts the fusion thread.
    /// `on_frame` (may be empty) is called from the fusion thread with each written frame.
    VideoStream(const io::Rig& rig, const VideoOptions& options, Context& context,
                std::function<void(const FusedFrame&)> on_frame);
    ~VideoStream();
    VideoStream(const VideoStream&) = delete;
    VideoStream& operator=(const VideoStream&) = delete;

    /// Hub thread: offers a formed frame set whose frames or views are in `history`.
    void offer(const io::FrameSet& set, const FrameHistory& history);
    /// Fuses what is pending, stops the thread and writes the final video.json.
    void finish(const std::string& stop_reason);
    /// Writing failed (disk full): the hub stops; the folder holds every frame before.
    bool failed() const { return failed_; }
    std::string error() const;
    /// Counters (also in video.json): sets offered, fused, skipped, empty, thinned, views
    /// fused / missing, CPU and wall ms of the fusion thread, latency p50 / p95.
    Report metrics() const;
    /// Cheap running totals for the hub's health check (cli/hub_health.hpp): sets offered,
    /// fused, skipped, and the fusion thread's wall and CPU time so far (ms).
    void totals(std::int64_t& offered, std::int64_t& fused, std::int64_t& skipped, double& wall_ms,
                double& cpu_ms) const;

private:
    void fuse(LiveSet& set);

    const io::Rig& rig_;
    VideoOptions options_;
    Context& context_;
    std::function<void(const FusedFrame&)> on_frame_;
    std::optional<Eigen::Vector3d> centre_;
    double voxel_m_ = 0;
    std::unique_ptr<io::VideoWriter> writer_;

    mutable std::mutex mutex_;  ///< guards error_ and the fusion thread's figures
    std::atomic<bool> failed_{false};
    std::string error_;
    std::atomic<std::int64_t> offered_{0}, fused_{0}, empty_{0}, thinned_{0}, views_fused_{0},
        views_missing_{0};
    double cpu_ms_ = 0, wall_ms_ = 0, max_wall_ms_ = 0;  ///< fusion thread (guarded by mutex_)
    std::vector<double> latency_ms_;                     ///< guarded by mutex_
    FusedFrame fused_frame_;
    std::vector<io::ColoredPoints> hub_views_;  ///< --fuse-on hub: the views made here
    cv::Mat color_;
    std::unique_ptr<tbb::task_arena> arena_;  ///< one thread: the fusion on one core
    NewestWorker<LiveSet> worker_;            ///< last: stopped before the members it uses go
};

}  // namespace rgbd::cli
