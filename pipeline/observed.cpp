#include "pipeline/observed.hpp"

#include "io/image_codec.hpp"
#include "pipeline/stages.hpp"
#include "toolkit/error.hpp"

namespace rgbd::pipeline {

namespace fs = std::filesystem;

std::vector<Eigen::Vector3d> Observations::world_points() const {
    std::vector<Eigen::Vector3d> out;
    for (const auto& v : views) {
        const Pose pose = v.view.frame == ViewFrame::kSensor && v.view.world_from_sensor
                              ? *v.view.world_from_sensor
                              : Pose::Identity();
        for (auto i : v.points) out.push_back(pose * to_eigen(v.points.point(i)));
    }
    return out;
}

fs::path segment_label_file(const io::Capture& capture, const std::string& sensor_id,
                            std::size_t position) {
    const io::FrameRecord& record = capture.frames.at(sensor_id).at(position);
    return capture.root / "gt" / sensor_id / "segment" / fs::path(record.depth).filename();
}

fs::path noise_label_file(const io::Capture& capture, const std::string& sensor_id,
                          std::size_t position) {
    const io::FrameRecord& record = capture.frames.at(sensor_id).at(position);
    return capture.root / "gt" / sensor_id / "labels" / fs::path(record.depth).filename();
}

namespace {

/// An 8-bit one-channel label image of the depth image's size, read from `file`.
cv::Mat read_label_image(const fs::path& file, const cv::Mat& depth) {
    cv::Mat label = io::read_image(file.string());
    RGBD_CHECK(label.type() == CV_8UC1 && label.cols == depth.cols && label.rows == depth.rows,
               file.string() + ": not an 8-bit one-channel image of the depth size (" +
                   std::to_string(depth.cols) + "x" + std::to_string(depth.rows) + ")");
    return label;
}

/// The subject labels of one frame: its segment labels, and, where the frame has noise labels,
/// every pixel whose depth is not a measurement of a surface (a flying pixel between two
/// surfaces, a random outlier: they keep the segment label of the surface their ray hits)
/// relabelled 0; the count of subject pixels so relabelled is added to `excluded`.
cv::Mat subject_labels(const io::Capture& capture, const std::string& sensor_id,
                       std::size_t position, const cv::Mat& depth, std::size_t& excluded) {
    cv::Mat label = read_label_image(segment_label_file(capture, sensor_id, position), depth);
    const fs::path noise_file = noise_label_file(capture, sensor_id, position);
    if (!fs::exists(noise_file)) return label;
    const cv::Mat noise = read_label_image(noise_file, depth);
    for (std::size_t p = 0; p < label.total(); ++p) {
        if (noise.data[p] == kNoiseLabelSurface || label.data[p] != evaluation::kLabelSubject)
            continue;
        label.data[p] = 0;
        ++excluded;
    }
    return label;
}

}  // namespace

Observations load_observations(const io::Capture& capture,
                               const std::vector<std::pair<std::string, std::size_t>>& frames,
                               const frames::CloudOptions& cloud_options,
                               const evaluation::SubjectOptions& subject,
                               const std::map<std::string, Pose>* poses) {
    const std::string root = capture.root.string();
    RGBD_CHECK(!frames.empty(), root + ": no frame selected");
    subject.check();
    Observations obs;
    std::vector<cv::Mat> labels;
    const bool labelled =
        fs::exists(segment_label_file(capture, frames[0].first, frames[0].second));
    Report per_view = Report::array();
    std::size_t noise_excluded = 0;
    int view_id = 0;
    bool masked = cloud_options.use_mask;
    for (const auto& [sensor_id, position] : frames) {
        RgbdFrame frame = io::load_frame(capture, sensor_id, position);
        if (poses) {
            const auto given = poses->find(sensor_id);
            RGBD_CHECK(given != poses->end(), root + ": no given pose for sensor " + sensor_id);
            frame.world_from_sensor = given->second;
            frame.has_pose = true;
        }
        const std::string name =
            root + ": frame " + std::to_string(frame.frame_index) + " of sensor " + sensor_id;
        RGBD_CHECK(frame.has_pose, name +
                                       " has no pose (rig.json world_from_depth or frames.csv "
                                       "pose columns); the observations need every view's pose");
        masked = masked && !frame.mask.empty();
        Report report;
        obs.views.push_back(view_from_frame(frame, view_id++, cloud_options, std::nullopt,
                                            ExtractionOptions{/*crop_radius_m=*/0.0}, report));
        if (labelled) {
            const fs::path file = segment_label_file(capture, sensor_id, position);
            RGBD_CHECK(fs::exists(file), file.string() +
                                             ": missing (the capture has subject labels for "
                                             "other frames)");
            labels.push_back(
                subject_labels(capture, sensor_id, position, frame.depth, noise_excluded));
        }
        per_view.push_back({{"sensor", sensor_id}, {"frame_index", frame.frame_index}});
    }
    const auto centre = object_centre(capture, frames);
    evaluation::SubjectOptions options = subject;
    options.remove_ground = options.remove_ground && !masked;  // masks left no ground
    obs.report = evaluation::observed_subject(obs.views, labels, centre, options);
    colour_hidden_points(obs.views);
    obs.report["views"] = obs.views.size();
    obs.report["labels"] =
        labelled ? Report((capture.root / "gt" / "<sensor>" / "segment").string()) : Report();
    if (labelled) obs.report["noise_excluded"] = noise_excluded;
    for (std::size_t v = 0; v < obs.views.size(); ++v) per_view[v]["points"] = obs.views[v].size();
    obs.report["per_view"] = per_view;
    obs.report["poses"] = poses ? "given" : "capture";
    RGBD_CHECK(obs.report["points"].get<std::size_t>() > 0,
               root + ": no observed subject point is left (selection " +
                   obs.report["selection"].get<std::string>() + ")");
    return obs;
}

}  // namespace rgbd::pipeline
