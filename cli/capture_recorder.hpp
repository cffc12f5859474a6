// rgbd-capture, the recording thread: frames and frame sets handed over as recycled jobs and
// written to a capture folder v1 with io::CaptureWriter. Used only by cli/rgbd_capture.cpp.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <zmq.hpp>

#include "cli/capture_control.hpp"
#include "cli/capture_live.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/rvl.hpp"
#include "sensors/network/clock_sync.hpp"
#include "sensors/network/frame_grouper.hpp"
#include "sensors/network/protocol.hpp"
#include "sensors/network/transport.hpp"
#include "sensors/sensor.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli::hub {

namespace net = rgbd::sensors::net;
namespace fs = std::filesystem;
using sensors::monotonic_ns;

// ---------------------------------------------------------------------------------- writer

/// A unit of work for the recording thread: a frame or a frame set. Jobs are recycled so
/// that buffers are reused (no allocation per frame once warmed up).
struct Job {
    bool is_set = false;
    std::size_t sensor = 0;
    std::int64_t index = 0, hub_ns = 0;
    cv::Mat depth;
    std::vector<std::uint8_t> jpeg;
    io::FrameSet set;
};

class Recorder {
public:
    /// An empty root records nothing (a live stream alone): jobs are only recycled.
    Recorder(const std::string& root, const io::Rig& rig, int png_compression)
        : rig_(rig), png_compression_(png_compression) {
        if (!root.empty()) writer_.emplace(root, rig);
        thread_ = std::thread([this] { run(); });
    }
    ~Recorder() { finish(); }

    std::unique_ptr<Job> take() {
        std::lock_guard<std::mutex> lock(mutex_);
        if (free_.empty()) return std::make_unique<Job>();
        auto job = std::move(free_.back());
        free_.pop_back();
        return job;
    }
    /// Returns an unused job to the pool.
    void push_back_free(std::unique_ptr<Job> job) {
        std::lock_guard<std::mutex> lock(mutex_);
        free_.push_back(std::move(job));
    }
    void push(std::unique_ptr<Job> job) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            queue_.push_back(std::move(job));
        }
        wake_.notify_one();
    }
    /// Waits until the queue is written (or writing failed) and stops the thread.
    void finish() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            done_ = true;
        }
        wake_.notify_one();
        if (thread_.joinable()) thread_.join();
    }
    bool failed() const { return failed_; }
    std::string error() {
        std::lock_guard<std::mutex> lock(mutex_);
        return error_;
    }
    std::int64_t frames_written() const { return frames_; }
    std::int64_t sets_written() const { return sets_; }
    std::size_t backlog() {
        std::lock_guard<std::mutex> lock(mutex_);
        return queue_.size();
    }
    bool recording() const { return writer_.has_value(); }
    fs::path root() const { return writer_ ? writer_->root() : fs::path(); }
    std::string depth_file(const std::string& sensor, std::int64_t index) const {
        return writer_->depth_file(sensor, index).string();
    }

private:
    void run() {
        for (;;) {
            std::unique_ptr<Job> job;
            {
                std::unique_lock<std::mutex> lock(mutex_);
                wake_.wait(lock, [&] { return !queue_.empty() || done_; });
                if (queue_.empty()) return;
                job = std::move(queue_.front());
                queue_.pop_front();
            }
            if (!failed_ && writer_) {
                try {
                    if (job->is_set) {
                        writer_->add_frameset(job->set);
                        ++sets_;
                    } else {
                        writer_->add_encoded_frame(rig_.sensors[job->sensor].id, job->index,
                                                   job->hub_ns, job->depth, job->jpeg,
                                                   png_compression_);
                        ++frames_;
                    }
                } catch (const std::exception& e) {
                    std::lock_guard<std::mutex> lock(mutex_);
                    error_ = e.what();
                    failed_ = true;
                }
            }
            std::lock_guard<std::mutex> lock(mutex_);
            free_.push_back(std::move(job));
        }
    }

    std::optional<io::CaptureWriter> writer_;
    const io::Rig& rig_;
    int png_compression_;
    std::mutex mutex_;
    std::condition_variable wake_;
    std::deque<std::unique_ptr<Job>> queue_;
    std::vector<std::unique_ptr<Job>> free_;
    bool done_ = false;
    std::atomic<bool> failed_{false};
    std::string error_;
    std::atomic<std::int64_t> frames_{0}, sets_{0};
    std::thread thread_;
};

}  // namespace rgbd::cli::hub
