#include "pipeline/source_evidence.hpp"

#include <tbb/parallel_for.h>

#include <filesystem>
#include <map>
#include <memory>
#include <optional>

#include "algorithms/segment/subject_extraction.hpp"
#include "io/capture_folder.hpp"
#include "toolkit/error.hpp"

namespace rgbd::pipeline {

namespace fs = std::filesystem;

Report SourceMeasurements::to_json() const {
    Report r = {{"points", points.size()},
                {"frames_read", frames_read},
                {"frames_missing", frames_missing}};
    if (!note.empty()) r["note"] = note;
    return r;
}

namespace {

/// The capture folder a depth frame's path lies in, opened (capture_root_of), or null.
std::shared_ptr<const io::Capture> capture_of(const std::string& source,
                                              const std::string& sensor_id) {
    if (source.empty() || sensor_id.empty()) return nullptr;
    fs::path dir = fs::path(source).parent_path();
    for (int level = 0; level < 4 && !dir.empty(); ++level, dir = dir.parent_path()) {
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) continue;
        try {
            auto capture = std::make_shared<const io::Capture>(io::open_capture(dir));
            if (capture->frames.count(sensor_id)) return capture;
        } catch (const std::exception&) {
            // not a capture folder: one level up
        }
        if (dir == dir.parent_path()) break;
    }
    return nullptr;
}

/// The frame of `view` in `capture`: its position in the sensor's frame list, or none.
std::optional<std::size_t> frame_position(const io::Capture& capture, const ViewInfo& view) {
    const auto it = capture.frames.find(view.sensor);
    if (it == capture.frames.end() || it->second.empty()) return std::nullopt;
    if (view.frame_index) return capture.find_frame(view.sensor, *view.frame_index);
    if (it->second.size() == 1) return std::size_t(0);
    return std::nullopt;
}

/// The valid pixels of `frame`'s depth inside `box` (and within `band` metres of `ground`, a
/// plane n . p + d in the sensor frame, when given), in the world frame of `world_from_sensor`.
void back_project(const RgbdFrame& frame, const Pose& world_from_sensor,
                  const Eigen::AlignedBox3d& box, const std::optional<Eigen::Vector4d>& ground,
                  double band, std::vector<Eigen::Vector3d>& out) {
    const cv::Mat& depth = frame.depth;
    const PinholeIntrinsics& k = frame.depth_intrinsics;
    for (int r = 0; r < depth.rows; ++r) {
        const float* row = depth.ptr<float>(r);
        for (int c = 0; c < depth.cols; ++c) {
            const float z = row[c];
            if (!(z > 0.0f) || !std::isfinite(z)) continue;
            const Eigen::Vector3d q = k.unproject(c, r, z);
            if (ground && std::abs(ground->head<3>().dot(q) + (*ground)(3)) > band) continue;
            const Eigen::Vector3d p = world_from_sensor * q;
            if (box.contains(p)) out.push_back(p);
        }
    }
}

}  // namespace

std::string capture_root_of(const std::string& source, const std::string& sensor_id) {
    const auto capture = capture_of(source, sensor_id);
    return capture ? capture->root.string() : std::string();
}

SourceMeasurements source_measurements(const std::vector<PointCloud>& views,
                                       const Eigen::AlignedBox3d& box, double ground_band) {
    SourceMeasurements result;
    // The captures the views come from, opened once (by the folder of their first source).
    std::map<std::string, std::shared_ptr<const io::Capture>> captures;
    struct Job {
        std::shared_ptr<const io::Capture> capture;  ///< null: nothing to read
        std::size_t position = 0;
        std::optional<Eigen::Vector4d> ground;  ///< the view's plane, with ground_band
        double band = 0;                        ///< metres
    };
    std::vector<Job> jobs(views.size());
    for (std::size_t i = 0; i < views.size(); ++i) {
        const ViewInfo& v = views[i].view;
        if (v.source.empty() || v.sensor.empty() || !v.world_from_sensor || !v.intrinsics) continue;
        Job job;
        if (ground_band > 0) {
            const auto g = segment::view_ground(views[i]);
            if (!g) continue;
            job.ground = Eigen::Vector4d(g->normal.x(), g->normal.y(), g->normal.z(), g->offset);
            job.band = ground_band * g->margin_m;
        }
        const std::string key = fs::path(v.source).parent_path().string() + "|" + v.sensor;
        auto it = captures.find(key);
        if (it == captures.end()) it = captures.emplace(key, capture_of(v.source, v.sensor)).first;
        const auto position = it->second ? frame_position(*it->second, v) : std::nullopt;
        if (!position) {
            ++result.frames_missing;
            if (result.note.empty())
                result.note = v.source + ": no capture folder holds this frame of sensor " +
                              v.sensor + "; the free-space evidence is the views' own points";
            continue;
        }
        job.capture = it->second;
        job.position = *position;
        jobs[i] = std::move(job);
    }
    std::vector<std::vector<Eigen::Vector3d>> per_view(views.size());
    std::vector<std::string> errors(views.size());
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t i) {
        const Job& job = jobs[i];
        if (!job.capture) return;
        try {
            const RgbdFrame frame =
                io::load_frame(*job.capture, views[i].view.sensor, job.position);
            back_project(frame, *views[i].view.world_from_sensor, box, job.ground, job.band,
                         per_view[i]);
        } catch (const std::exception& e) {
            errors[i] = e.what();
        }
    });
    for (std::size_t i = 0; i < views.size(); ++i) {
        if (!jobs[i].capture) continue;
        if (!errors[i].empty()) {
            ++result.frames_missing;
            if (result.note.empty()) result.note = errors[i];
            continue;
        }
        ++result.frames_read;
        result.points.insert(result.points.end(), per_view[i].begin(), per_view[i].end());
    }
    return result;
}

}  // namespace rgbd::pipeline
