#include "sensors/playback/playback_sensor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "io/image_codec.hpp"
#include "toolkit/error.hpp"

namespace rgbd::sensors {

namespace fs = std::filesystem;

namespace {

std::vector<std::uint8_t> read_bytes(const fs::path& path) {
    std::vector<std::uint8_t> bytes = io::read_file_bytes(path.string());
    if (bytes.empty()) throw InputError(path.string() + ": empty colour image");
    return bytes;
}

bool is_jpeg(const fs::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    return ext == ".jpg" || ext == ".jpeg";
}

}  // namespace

PlaybackSensor::PlaybackSensor(const fs::path& root, const std::string& sensor_id,
                               const PlaybackOptions& options)
    : capture_(io::open_capture(root)), options_(options) {
    check_range("playback: default rate", options.default_rate_hz, Range::open_closed(0, 1000),
                "Hz");
    RGBD_CHECK(options.max_frames >= 0, "playback: max frames must be >= 0");
    std::string id = sensor_id;
    if (id.empty()) {
        if (capture_.rig.sensors.size() != 1)
            throw InputError(root.string() + ": capture has " +
                             std::to_string(capture_.rig.sensors.size()) +
                             " sensors: name one (playback:FOLDER#ID)");
        id = capture_.rig.sensors.front().id;
    }
    spec_ = capture_.rig.sensor(id);
    spec_.depth_encoding = io::DepthEncoding::kPlain;  // load() decodes the files' encoding
    records_ = capture_.frames.at(id);
    if (records_.empty()) throw InputError(root.string() + ": sensor '" + id + "' has no frames");

    // Recorded instants in hub time; the capture's start is the earliest frame of any sensor,
    // so that sensors of one capture keep their recorded phase.
    std::int64_t start = std::numeric_limits<std::int64_t>::max();
    std::int64_t end = std::numeric_limits<std::int64_t>::min();
    for (const io::SensorSpec& s : capture_.rig.sensors)
        for (const io::FrameRecord& r : capture_.frames.at(s.id)) {
            start = std::min(start, r.time_ns - s.clock_offset_ns);
            end = std::max(end, r.time_ns - s.clock_offset_ns);
        }
    std::vector<std::int64_t> steps;
    for (std::size_t j = 0; j < records_.size(); ++j) {
        offset_ns_.push_back(records_[j].time_ns - spec_.clock_offset_ns - start);
        if (j > 0) {
            if (records_[j].time_ns < records_[j - 1].time_ns)
                throw InputError(root.string() + ": sensor '" + id +
                                 "': frame times go backwards at index " +
                                 std::to_string(records_[j].index));
            steps.push_back(records_[j].time_ns - records_[j - 1].time_ns);
        }
    }
    if (!steps.empty()) {
        std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
        period_ns_ = steps[steps.size() / 2];
    }
    if (steps.empty() || period_ns_ <= 0)
        period_ns_ = static_cast<std::int64_t>(std::llround(1e9 / options.default_rate_hz));
    const std::int64_t span = end - start + period_ns_;
    loop_ns_ = (span + period_ns_ - 1) / period_ns_ * period_ns_;

    if (options_.preload) {
        frames_.resize(records_.size());
        for (std::size_t j = 0; j < records_.size(); ++j) load(j, frames_[j]);
    }
}

void PlaybackSensor::load(std::size_t position, Stored& out) const {
    const io::FrameRecord& r = records_[position];
    const auto resolve = [&](const std::string& p) {
        const fs::path path(p);
        return path.is_absolute() ? path : capture_.root / spec_.id / path;
    };
    const fs::path depth_file = resolve(r.depth);
    out.depth = io::read_image(depth_file.string());
    if (out.depth.type() != CV_16UC1)
        throw InputError(depth_file.string() + ": depth image is not 16-bit single-channel");
    if (out.depth.cols != spec_.depth.width || out.depth.rows != spec_.depth.height)
        throw InputError(depth_file.string() + ": depth is " + std::to_string(out.depth.cols) +
                         "x" + std::to_string(out.depth.rows) + ", the rig says " +
                         std::to_string(spec_.depth.width) + "x" +
                         std::to_string(spec_.depth.height));
    io::decode_depth(out.depth, capture_.rig.sensor(spec_.id).depth_encoding);
    out.color.release();
    out.color_jpeg.clear();
    if (!r.color.empty()) {
        const fs::path color_file = resolve(r.color);
        if (is_jpeg(color_file) && !options_.decode_color) {
            out.color_jpeg = read_bytes(color_file);
        } else {
            out.color = io::read_image(color_file.string(), io::ImageMode::kColor);
        }
    }
}

bool PlaybackSensor::start_at(std::int64_t monotonic_ns) {
    if (started_) return false;
    start_ns_ = monotonic_ns;
    return true;
}

bool PlaybackSensor::next(SensorFrame& frame) {
    if (options_.max_frames > 0 && produced_ >= options_.max_frames) return false;
    const std::int64_t n = static_cast<std::int64_t>(records_.size());
    if (!options_.loop && produced_ >= n) return false;
    const std::int64_t loop = produced_ / n;
    const std::size_t position = static_cast<std::size_t>(produced_ % n);

    if (!started_) {
        started_ = true;
        if (start_ns_) {
            origin_ns_ = *start_ns_ - offset_ns_[0];
        } else {
            const std::int64_t lead = 20'000'000;  // let the caller get ready: 20 ms
            const std::int64_t now = monotonic_ns() + lead;
            if (options_.realtime && options_.align_to_clock) {
                // first grid origin whose first frame is still ahead
                origin_ns_ = (now - offset_ns_[0] + loop_ns_ - 1) / loop_ns_ * loop_ns_;
            } else {
                origin_ns_ = now - offset_ns_[0];
            }
        }
    }
    const std::int64_t instant = origin_ns_ + loop * loop_ns_ + offset_ns_[position];
    if (options_.realtime) {
        const std::int64_t wait = instant - monotonic_ns();
        if (wait > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
    }
    const Stored* stored = &scratch_;
    if (options_.preload) {
        stored = &frames_[position];
    } else {
        load(position, scratch_);
    }
    stored->depth.copyTo(frame.depth);
    if (stored->color.empty()) {
        frame.color.release();
    } else {
        stored->color.copyTo(frame.color);
    }
    frame.color_jpeg.assign(stored->color_jpeg.begin(), stored->color_jpeg.end());
    frame.index = produced_;
    frame.capture_ns = options_.realtime ? instant : monotonic_ns();
    frame.device_ns = records_[position].time_ns + loop * loop_ns_;
    frame.source_position = static_cast<std::int64_t>(position);
    ++produced_;
    return true;
}

}  // namespace rgbd::sensors
