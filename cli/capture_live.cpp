#include "cli/capture_live.hpp"

#include <chrono>
#include <iostream>

#include "cli/common/tool.hpp"
#include "io/image_codec.hpp"
#include "io/output_file.hpp"
#include "io/ply_stream.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli {

// ------------------------------------------------------------------------------ FrameHistory

FrameHistory::FrameHistory(std::size_t sensors, std::int64_t window_ns)
    : window_ns_(window_ns), frames_(sensors) {}

LiveFrame& FrameHistory::slot(std::size_t sensor, std::int64_t index, std::int64_t hub_ns) {
    auto& list = frames_.at(sensor);
    while (!list.empty() && list.front()->hub_ns < hub_ns - window_ns_) {
        free_.push_back(std::move(list.front()));
        list.pop_front();
    }
    std::unique_ptr<LiveFrame> frame;
    if (free_.empty()) {
        frame = std::make_unique<LiveFrame>();
    } else {
        frame = std::move(free_.back());
        free_.pop_back();
    }
    frame->index = index;
    frame->hub_ns = hub_ns;
    list.push_back(std::move(frame));
    return *list.back();
}

void FrameHistory::store(std::size_t sensor, std::int64_t index, std::int64_t hub_ns,
                         const cv::Mat& depth, const std::uint8_t* jpeg, std::size_t jpeg_bytes) {
    LiveFrame& frame = slot(sensor, index, hub_ns);
    frame.is_view = false;
    depth.copyTo(frame.depth);  // same size and type: the buffer is reused
    frame.jpeg.assign(jpeg, jpeg + jpeg_bytes);
}

void FrameHistory::store_view(std::size_t sensor, std::int64_t index, std::int64_t hub_ns,
                              const io::ColoredPoints& points) {
    LiveFrame& frame = slot(sensor, index, hub_ns);
    frame.is_view = true;
    frame.points.xyz.assign(points.xyz.begin(), points.xyz.end());
    frame.points.rgb.assign(points.rgb.begin(), points.rgb.end());
}

const LiveFrame* FrameHistory::find(std::size_t sensor, std::int64_t index) const {
    const auto& list = frames_.at(sensor);
    // Indices grow by one per frame of a sensor (a restarted node goes on counting), so the
    // frame sits at a known distance from the newest one.
    for (auto it = list.rbegin(); it != list.rend(); ++it) {
        if ((*it)->index == index) return it->get();
        if ((*it)->index < index) break;
    }
    return nullptr;
}

// ------------------------------------------------------------------------------ LiveStream

void copy_frame(const LiveFrame& from, LiveFrame& to) {
    to.index = from.index;
    to.hub_ns = from.hub_ns;
    from.depth.copyTo(to.depth);
    to.jpeg.assign(from.jpeg.begin(), from.jpeg.end());
    to.is_view = from.is_view;
    to.points.xyz.assign(from.points.xyz.begin(), from.points.xyz.end());
    to.points.rgb.assign(from.points.rgb.begin(), from.points.rgb.end());
}

RgbdFrame rgbd_from_live(const io::SensorSpec& spec, const LiveFrame& frame, cv::Mat& color) {
    const std::string what = "live frame " + std::to_string(frame.index) + " of sensor " + spec.id;
    color.release();
    if (!frame.jpeg.empty()) {
        try {
            color = io::decode_image(frame.jpeg, io::ImageMode::kColor);
        } catch (const IoError& e) {
            throw InputError(what + ": cannot decode the colour JPEG: " + e.what());
        }
    }
    RgbdFrame rgbd = io::frame_from_stored(spec, frame.depth, color, what);
    rgbd.frame_index = frame.index;
    rgbd.timestamp_ns = frame.hub_ns;
    return rgbd;
}

LiveStream::LiveStream(const io::Rig& rig, const LiveOptions& options, Context& context,
                       std::function<int(std::int64_t)> on_disk,
                       std::function<std::string(const std::string&, std::int64_t)> depth_file)
    : rig_(rig),
      options_(options),
      context_(context),
      on_disk_(std::move(on_disk)),
      depth_file_(std::move(depth_file)),
      centre_(object_centre(rig)),
      worker_([this](LiveSet& set) { take(set); }) {
    if (options_.path == "-") {
        out_ = &std::cout;
    } else {
        file_ = std::make_unique<io::OutputFile>(options_.path, "--live " + options_.path);
        out_ = &file_->stream();
    }
}

LiveStream::~LiveStream() {
    worker_.stop(false);  // an output file not put in place by finish() removes its temporary
}

void LiveStream::offer(const io::FrameSet& set, std::int64_t ordinal, const FrameHistory& history) {
    if (finished_) return;
    for (const std::int64_t index : set.frames)
        if (index < 0) {
            ++incomplete_;
            return;
        }
    LiveSet& staging = worker_.staging();
    staging.frames.resize(rig_.sensors.size());
    for (std::size_t s = 0; s < set.frames.size(); ++s) {
        const LiveFrame* frame = history.find(s, set.frames[s]);
        if (!frame) {  // older than the history window: cannot happen with matching latency
            ++incomplete_;
            return;
        }
        copy_frame(*frame, staging.frames[s]);
    }
    staging.set = set;
    staging.ordinal = ordinal;
    worker_.commit();
}

void LiveStream::take(LiveSet& set) {
    if (finished_) return;
    emit(set);
    if (options_.max_sets > 0 && emitted_ >= options_.max_sets) finished_ = true;
}

void LiveStream::emit(const LiveSet& live) {
    // With a recording, wait until the set and its frames are on disk, so the views can name
    // their depth image and a downstream rgbd-upsample can open it (10 s at most).
    int on_disk = on_disk_(live.ordinal);
    for (int k = 0; on_disk == 0 && k < 5000; ++k) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        on_disk = on_disk_(live.ordinal);
    }
    // The set's views first: the object extraction looks at them together, as rgbd-cloud does.
    std::vector<PointCloud> views;
    for (std::size_t s = 0; s < rig_.sensors.size(); ++s) {
        const io::SensorSpec& spec = rig_.sensors[s];
        const LiveFrame& frame = live.frames[s];
        const std::string what =
            "live frame " + std::to_string(frame.index) + " of sensor " + spec.id;
        Report report;
        try {
            RgbdFrame rgbd = rgbd_from_live(spec, frame, color_);
            if (on_disk == 1) rgbd.source = depth_file_(spec.id, frame.index);
            views.push_back(view_from_frame(rgbd, static_cast<int>(s), options_.cloud, centre_,
                                            /*extraction=*/{0.0}, report));
        } catch (const Error& e) {
            context_.warn(std::string("live stream: ") + e.what() + "; view left out");
            continue;
        } catch (const cv::Exception& e) {
            context_.warn("live stream: " + what + ": " + e.what() + "; view left out");
            continue;
        }
    }
    try {
        pipeline::extract_stage(views, centre_, options_.extraction);
    } catch (const Error& e) {
        context_.warn("live stream: set " + std::to_string(live.ordinal) + ": " + e.what() +
                      "; its views are left out");
        views.clear();
    }
    for (PointCloud& view : views) {
        io::Document document;
        document.cloud = std::move(view);
        bool written = true;
        try {
            io::write_document(*out_, document);
        } catch (const IoError&) {  // the writer reports a failed stream
            written = false;
        }
        if (!written || !out_->good()) break;
        ++views_;
    }
    if (out_->good()) out_->flush();
    if (!out_->good()) {
        closed_ = true;
        finished_ = true;
        context_.warn(
            "live stream: " + (options_.path == "-" ? std::string("<stdout>") : options_.path) +
            ": the reader went away; the hub goes on");
        return;
    }
    ++emitted_;
}

void LiveStream::finish() {
    worker_.stop(true);
    if (!file_) return;
    // A FIFO whose reader went away was warned about; a regular file must be whole.
    if (file_->in_place()) {
        file_->close();
        return;
    }
    if (closed_) throw IoError("--live " + options_.path + ": write failed (disk full?)");
    file_->commit();
}

Report LiveStream::metrics() const {
    return Report{{"sets_emitted", emitted_.load()},
                  {"sets_skipped", worker_.skipped()},
                  {"sets_incomplete", incomplete_.load()},
                  {"views", views_.load()},
                  {"reader_closed", closed_.load()}};
}

}  // namespace rgbd::cli
