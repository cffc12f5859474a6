// A worker thread that always takes the newest offered item (rgbd-capture's live view stream and
// 3D video fusion): the hub fills staging() and commits it; an item still waiting when the next
// one is committed is replaced and counted as skipped, never queued, so the hub never waits for
// a slow consumer and memory stays bounded. Three buffers (staging, pending, working) are
// swapped, never copied: no allocation per item once warmed up.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>

namespace rgbd::cli {

template <typename T>
class NewestWorker {
public:
    /// Starts the thread; `work` runs on it for every item it takes.
    explicit NewestWorker(std::function<void(T&)> work) : work_(std::move(work)) {
        thread_ = std::thread([this] { run(); });
    }
    ~NewestWorker() { stop(false); }
    NewestWorker(const NewestWorker&) = delete;
    NewestWorker& operator=(const NewestWorker&) = delete;

    /// Producer thread: the buffer to fill before commit().
    T& staging() { return staging_; }
    /// Producer thread: hands staging() over (replacing a waiting item: skipped).
    void commit() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (has_pending_) ++skipped_;
            std::swap(staging_, pending_);
            has_pending_ = true;
        }
        wake_.notify_one();
    }
    /// Stops the thread; with `drain` a waiting item is processed first. Idempotent.
    void stop(bool drain) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
            if (!drain) has_pending_ = false;
        }
        wake_.notify_one();
        if (thread_.joinable()) thread_.join();
    }
    std::int64_t skipped() const { return skipped_; }

private:
    void run() {
        for (;;) {
            {
                std::unique_lock<std::mutex> lock(mutex_);
                wake_.wait(lock, [&] { return has_pending_ || stop_; });
                if (!has_pending_) return;
                std::swap(pending_, working_);
                has_pending_ = false;
            }
            work_(working_);
        }
    }

    std::function<void(T&)> work_;
    T staging_, pending_, working_;  ///< producer-owned, shared, worker-owned
    bool has_pending_ = false, stop_ = false;
    std::mutex mutex_;
    std::condition_variable wake_;
    std::atomic<std::int64_t> skipped_{0};
    std::thread thread_;
};

}  // namespace rgbd::cli
