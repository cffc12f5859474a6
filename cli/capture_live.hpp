// rgbd-capture --live: the newest frame sets as a view stream for a live pipeline
// (docs/formats.md, docs/algorithms.md §1). The hub keeps the last frames of every sensor in memory
// (FrameHistory), hands each complete frame set to LiveStream, and a thread of its own turns the
// newest set into views (io::frame_from_stored + view_from_frame, exactly what rgbd-cloud does with
// the recorded folder) and writes them. A reader slower than the sensors gets the newest set each
// time it is ready; the sets in between are skipped and counted, never queued, so the hub and the
// recording never wait for the pipeline.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>
#include <thread>
#include <vector>

#include "cli/common/stages.hpp"
#include "cli/newest_worker.hpp"
#include "io/capture_folder.hpp"
#include "io/output_file.hpp"
#include "io/video.hpp"
#include "toolkit/report.hpp"

namespace rgbd::cli {

class Context;

/// One received frame in its stored form.
struct LiveFrame {
    std::int64_t index = -1;         ///< the frame's index in the recording (frames.csv)
    std::int64_t hub_ns = 0;         ///< hub time
    cv::Mat depth;                   ///< CV_16UC1, the sensor's depth_scale units
    std::vector<std::uint8_t> jpeg;  ///< colour as received (empty = none)
    bool is_view = false;            ///< a node's view (--fuse-on nodes): points, no depth
    io::ColoredPoints points;        ///< the view's points, world frame
};

/// The frames of every sensor received in the last `window_ns` of hub time. Buffers are
/// recycled: no allocation per frame once warmed up.
class FrameHistory {
public:
    FrameHistory(std::size_t sensors, std::int64_t window_ns);
    /// Copies a frame in; forgets the sensor's frames older than its newest minus the window.
    void store(std::size_t sensor, std::int64_t index, std::int64_t hub_ns, const cv::Mat& depth,
               const std::uint8_t* jpeg, std::size_t jpeg_bytes);
    /// Copies a node's view in (rgbd-capture --video --fuse-on nodes).
    void store_view(std::size_t sensor, std::int64_t index, std::int64_t hub_ns,
                    const io::ColoredPoints& points);
    /// The sensor's frame with that index, or nullptr when it is not (or no longer) here.
    const LiveFrame* find(std::size_t sensor, std::int64_t index) const;

private:
    std::int64_t window_ns_;
    std::vector<std::deque<std::unique_ptr<LiveFrame>>> frames_;  ///< per sensor, by index
    std::vector<std::unique_ptr<LiveFrame>> free_;
    LiveFrame& slot(std::size_t sensor, std::int64_t index, std::int64_t hub_ns);
};

/// Copies a frame (buffers of `to` reused).
void copy_frame(const LiveFrame& from, LiveFrame& to);

/// A received frame as an RgbdFrame of `spec` (colour JPEG decoded into `color`, reused),
/// frame index and hub time set. Throws InputError naming the frame and sensor.
RgbdFrame rgbd_from_live(const io::SensorSpec& spec, const LiveFrame& frame, cv::Mat& color);

/// A frame set with copies of its frames (in Rig::sensors order).
struct LiveSet {
    std::int64_t ordinal = -1;  ///< position of the set in the recording's framesets.csv
    io::FrameSet set;
    std::vector<LiveFrame> frames;
};

struct LiveOptions {
    std::string path =
        "-";  ///< "-" = stdout; a FIFO or device is written directly, a file atomically
    long long max_sets = 0;      ///< stop after this many sets (0 = no limit)
    frames::CloudOptions cloud;  ///< as rgbd-cloud's defaults
    /// The object extraction over each set's views, as rgbd-cloud's defaults.
    pipeline::SubjectStageOptions extraction;
};

class LiveStream {
public:
    /// `on_disk(ordinal)`: 1 when the recording holds that set and its frames (views then name
    /// their recorded depth image as rgbd:view.source, so rgbd-upsample finds the colour),
    /// 0 not yet, -1 never (no recording, or it failed). `depth_file(sensor, index)`: that
    /// image's path.
    LiveStream(const io::Rig& rig, const LiveOptions& options, Context& context,
               std::function<int(std::int64_t)> on_disk,
               std::function<std::string(const std::string&, std::int64_t)> depth_file);
    ~LiveStream();
    LiveStream(const LiveStream&) = delete;
    LiveStream& operator=(const LiveStream&) = delete;

    /// Hub thread: offers a formed frame set. Complete sets whose frames are all in `history`
    /// become the newest pending set (replacing one the stream has not taken: skipped).
    void offer(const io::FrameSet& set, std::int64_t ordinal, const FrameHistory& history);
    /// --live-sets reached, or the reader went away: the hub may stop.
    bool finished() const { return finished_; }
    /// The reader went away (the stream is finished; a recording goes on).
    bool reader_closed() const { return closed_; }
    /// Streams what is pending (unless finished), stops the thread and puts a file output in
    /// place. Throws IoError when the output cannot be completed.
    void finish();
    /// sets emitted / skipped / incomplete, views, whether the reader closed the stream.
    Report metrics() const;

private:
    void take(LiveSet& set);
    void emit(const LiveSet& set);

    const io::Rig& rig_;
    LiveOptions options_;
    Context& context_;
    std::function<int(std::int64_t)> on_disk_;
    std::function<std::string(const std::string&, std::int64_t)> depth_file_;
    std::optional<Eigen::Vector3d> centre_;
    std::ostream* out_ = nullptr;
    std::unique_ptr<io::OutputFile> file_;  ///< unless the output is stdout

    std::atomic<bool> finished_{false}, closed_{false};
    std::atomic<std::int64_t> emitted_{0}, incomplete_{0}, views_{0};
    cv::Mat color_;                 ///< decoded colour, reused
    NewestWorker<LiveSet> worker_;  ///< last: stopped before the members it uses go
};

}  // namespace rgbd::cli
