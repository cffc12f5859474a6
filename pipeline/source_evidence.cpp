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

std::string capture_root_of(const std::string& source, const std::string& sensor_id) {
    if (source.empty() || sensor_id.empty()) return {};
    fs::path dir = fs::path(source).parent_path();
    for (int level = 0; level < 4 && !dir.empty(); ++level, dir = dir.parent_path()) {
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) continue;
        try {
            const io::Capture capture = io::open_capture(dir);
            if (capture.frames.count(sensor_id)) return dir.string();
        } catch (const std::exception&) {
            // not a capture folder: one level up
        }
        if (dir == dir.parent_path()) break;
    }
    return {};
}

namespace {

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

SourceMeasurements source_measurements(const std::vector<PointCloud>& views,
                                       const Eigen::AlignedBox3d& box, double ground_band) {
    SourceMeasurements result;
    // The captures the views come from, opened once (by the folder of their first source).
    std::map<std::string, std::shared_ptr<const io::Capture>> captures;
    std::vector<std::pair<std::shared_ptr<const io::Capture>, std::size_t>> jobs(views.size());
    for (std::size_t i = 0; i < views.size(); ++i) {
        const ViewInfo& v = views[i].view;
        if (v.source.empty() || v.sensor.empty() || !v.world_from_sensor || !v.intrinsics) continue;
        if (ground_band > 0 && !segment::view_ground(views[i])) continue;
        const std::string key = fs::path(v.source).parent_path().string() + "|" + v.sensor;
        auto it = captures.find(key);
        if (it == captures.end()) {
            std::shared_ptr<const io::Capture> capture;
            const std::string root = capture_root_of(v.source, v.sensor);
            if (!root.empty()) capture = std::make_shared<io::Capture>(io::open_capture(root));
            it = captures.emplace(key, capture).first;
        }
        const auto position = it->second ? frame_position(*it->second, v) : std::nullopt;
        if (!position) {
            ++result.frames_missing;
            if (result.note.empty())
                result.note = v.source + ": no capture folder holds this frame of sensor " +
                              v.sensor + "; the free-space evidence is the views' own points";
            continue;
        }
        jobs[i] = {it->second, *position};
    }
    std::vector<std::vector<Eigen::Vector3d>> per_view(views.size());
    std::vector<std::string> errors(views.size());
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t i) {
        if (!jobs[i].first) return;
        try {
            const RgbdFrame frame =
                io::load_frame(*jobs[i].first, views[i].view.sensor, jobs[i].second);
            std::optional<Eigen::Vector4d> plane;
            double band = 0;
            if (ground_band > 0) {
                const segment::ViewGround g = *segment::view_ground(views[i]);
                plane = Eigen::Vector4d(g.normal.x(), g.normal.y(), g.normal.z(), g.offset);
                band = ground_band * g.margin_m;
            }
            back_project(frame, *views[i].view.world_from_sensor, box, plane, band, per_view[i]);
        } catch (const std::exception& e) {
            errors[i] = e.what();
        }
    });
    for (std::size_t i = 0; i < views.size(); ++i) {
        if (!jobs[i].first) continue;
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
