#include "cli/capture_video.hpp"

#include <time.h>

#include <algorithm>

#include "cli/common/tool.hpp"
#include "sensors/sensor.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli {

namespace {

double thread_cpu_ms() {
    timespec ts{};
    ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    const auto k = static_cast<std::size_t>(std::min<double>(
        static_cast<double>(v.size() - 1), std::floor(q * static_cast<double>(v.size()))));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
}

}  // namespace

VideoStream::VideoStream(const io::Rig& rig, const VideoOptions& options, Context& context,
                         std::function<void(const FusedFrame&)> on_frame)
    : rig_(rig),
      options_(options),
      context_(context),
      on_frame_(std::move(on_frame)),
      centre_(pipeline::object_centre(rig)),
      // The fusion runs on one core (a one-thread arena: parallel loops inside run serially),
      // so its thread CPU time is the hub's work per set on one core.
      arena_(std::make_unique<tbb::task_arena>(1)),
      worker_([this](LiveSet& set) {
          if (!failed_) arena_->execute([&] { fuse(set); });
      }) {
    options_.fusion.check();
    voxel_m_ = options_.fusion.voxel_m > 0 ? options_.fusion.voxel_m
                                           : pipeline::video_voxel_m(rig, centre_);
    nlohmann::json header = {{"placement", options_.fuse_on_nodes ? "nodes" : "hub"},
                             {"voxel_m", voxel_m_},
                             {"crop_radius_m", options_.fusion.extraction.crop_radius_m},
                             {"clean", options_.fusion.clean},
                             {"duplicate_radius_voxels", options_.fusion.duplicate_radius_voxels},
                             {"sensors", rig.sensors.size()}};
    if (centre_) header["object_centre"] = {centre_->x(), centre_->y(), centre_->z()};
    writer_ = std::make_unique<io::VideoWriter>(options_.dir, rig, options_.frame_rate_hz,
                                                options_.draco, header);
}

VideoStream::~VideoStream() { worker_.stop(false); }

std::string VideoStream::error() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return error_;
}

void VideoStream::offer(const io::FrameSet& set, const FrameHistory& history) {
    ++offered_;
    if (failed_) return;
    const std::size_t n = rig_.sensors.size();
    LiveSet& staging = worker_.staging();
    staging.frames.resize(n);
    int present = 0;
    for (std::size_t s = 0; s < n; ++s) {
        const LiveFrame* frame =
            s < set.frames.size() && set.frames[s] >= 0 ? history.find(s, set.frames[s]) : nullptr;
        if (!frame) {
            staging.frames[s].index = -1;
            continue;
        }
        copy_frame(*frame, staging.frames[s]);
        ++present;
    }
    if (present == 0) {
        ++empty_;
        return;
    }
    staging.set = set;
    staging.ordinal = set.set;
    worker_.commit();
}

void VideoStream::fuse(LiveSet& live) {
    const std::int64_t wall0 = sensors::monotonic_ns();
    const double cpu0 = thread_cpu_ms();
    std::vector<pipeline::FusionView> views;
    hub_views_.resize(rig_.sensors.size());
    int sensors_used = 0;
    for (std::size_t s = 0; s < rig_.sensors.size(); ++s) {
        const LiveFrame& frame = live.frames[s];
        if (frame.index < 0) {
            ++views_missing_;
            continue;
        }
        const io::SensorSpec& spec = rig_.sensors[s];
        try {
            const io::ColoredPoints* points = &frame.points;
            if (!frame.is_view) {  // --fuse-on hub: the per-view work here
                const RgbdFrame rgbd = rgbd_from_live(spec, frame, color_);
                hub_views_[s] = io::to_colored_points(
                    pipeline::fusion_view(rgbd, static_cast<int>(s), options_.fusion, centre_));
                points = &hub_views_[s];
            }
            views.push_back({points, spec.world_from_depth.translation()});
            ++sensors_used;
        } catch (const Error& e) {
            context_.warn(std::string("video: ") + e.what() + "; view left out");
            ++views_missing_;
        } catch (const cv::Exception& e) {
            context_.warn(std::string("video: ") + e.what() + "; view left out");
            ++views_missing_;
        }
    }
    views_fused_ += sensors_used;
    if (sensors_used < static_cast<int>(rig_.sensors.size())) ++thinned_;
    fused_frame_.points = pipeline::fuse_points(views, voxel_m_, options_.fusion);
    io::VideoFrame info;
    info.set = live.set.set;
    info.time_ns = live.set.time_ns;
    info.spread_ns = live.set.spread_ns;
    info.sensors = sensors_used;
    try {
        fused_frame_.info = writer_->add(fused_frame_.points, info);
    } catch (const Error& e) {
        std::lock_guard<std::mutex> lock(mutex_);
        error_ = e.what();
        failed_ = true;
        return;
    }
    const std::int64_t now = sensors::monotonic_ns();
    const double cpu_ms = thread_cpu_ms() - cpu0;
    const double wall_ms = 1e-6 * static_cast<double>(now - wall0);
    const double latency_ms = 1e-6 * static_cast<double>(now - live.set.time_ns);
    try {
        writer_->update_last(cpu_ms, latency_ms);
    } catch (const Error& e) {
        std::lock_guard<std::mutex> lock(mutex_);
        error_ = e.what();
        failed_ = true;
    }
    fused_frame_.info.hub_ms = cpu_ms;
    fused_frame_.info.latency_ms = latency_ms;
    fused_frame_.frame = fused_frame_.info.frame;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        cpu_ms_ += thread_cpu_ms() - cpu0;  // with the index rewrites
        wall_ms_ += wall_ms;
        max_wall_ms_ = std::max(max_wall_ms_, wall_ms);
        latency_ms_.push_back(latency_ms);
    }
    ++fused_;
    if (on_frame_) on_frame_(fused_frame_);
}

void VideoStream::finish(const std::string& stop_reason) {
    worker_.stop(true);
    if (failed_) {
        // Name what was kept: the index lists every frame written before the error.
        try {
            writer_->finish(metrics(), "write failed: " + error());
        } catch (const Error&) {
        }
        return;
    }
    writer_->finish(metrics(), stop_reason);
}

void VideoStream::totals(std::int64_t& offered, std::int64_t& fused, std::int64_t& skipped,
                         double& wall_ms, double& cpu_ms) const {
    std::lock_guard<std::mutex> lock(mutex_);
    offered = offered_.load();
    fused = fused_.load();
    skipped = worker_.skipped();
    wall_ms = wall_ms_;
    cpu_ms = cpu_ms_;
}

Report VideoStream::metrics() const {
    std::lock_guard<std::mutex> lock(mutex_);
    const double fused = static_cast<double>(fused_.load());
    return Report{{"sets_offered", offered_.load()},
                  {"sets_fused", fused_.load()},
                  {"sets_skipped", worker_.skipped()},
                  {"sets_empty", empty_.load()},
                  {"sets_thinned", thinned_.load()},
                  {"views_fused", views_fused_.load()},
                  {"views_missing", views_missing_.load()},
                  {"voxel_m", voxel_m_},
                  {"hub_cpu_ms_per_set", fused > 0 ? cpu_ms_ / fused : 0.0},
                  {"hub_wall_ms_per_set", fused > 0 ? wall_ms_ / fused : 0.0},
                  {"hub_wall_ms_max", max_wall_ms_},
                  {"latency_ms_p50", percentile(latency_ms_, 0.5)},
                  {"latency_ms_p95", percentile(latency_ms_, 0.95)},
                  {"bytes", writer_ ? writer_->bytes() : 0}};
}

}  // namespace rgbd::cli
