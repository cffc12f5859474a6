#include "pipeline/stages.hpp"

#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "algorithms/frames/object_extraction.hpp"
#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/sampling/merge_views.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "pipeline/source_evidence.hpp"
#include "toolkit/error.hpp"

namespace rgbd::pipeline {

namespace fs = std::filesystem;

std::optional<Eigen::Vector3d> object_centre(
    const io::Capture& capture, const std::vector<std::pair<std::string, std::size_t>>& jobs) {
    std::vector<Pose> poses;
    for (const auto& [id, position] : jobs) {
        const io::FrameRecord& record = capture.frames.at(id).at(position);
        const io::SensorSpec& sensor = capture.rig.sensor(id);
        if (record.world_from_depth)
            poses.push_back(*record.world_from_depth);
        else if (sensor.has_world_from_depth)
            poses.push_back(sensor.world_from_depth);
        else
            return std::nullopt;
    }
    return frames::axes_convergence_point(poses);
}

std::optional<Eigen::Vector3d> object_centre(const io::Rig& rig) {
    std::vector<Pose> poses;
    for (const io::SensorSpec& sensor : rig.sensors) {
        if (!sensor.has_world_from_depth) return std::nullopt;
        poses.push_back(sensor.world_from_depth);
    }
    return frames::axes_convergence_point(poses);
}

namespace {
constexpr const char* kNoiseKey = "rgbd:sensor.noise_model ";
}  // namespace

std::optional<denoise::NoiseModel> frame_noise_model(const RgbdFrame& frame) {
    for (const std::string& name : {frame.noise_model, frame.sensor_model}) {
        if (name.empty()) continue;
        try {
            return denoise::parse_noise_model(name);
        } catch (const InputError&) {
        }
    }
    return std::nullopt;
}

std::optional<denoise::NoiseModel> view_noise_model(const PointCloud& view) {
    for (const auto& c : view.view.extra_comments) {
        if (c.rfind(kNoiseKey, 0) != 0) continue;
        try {
            return denoise::parse_noise_model(c.substr(std::string(kNoiseKey).size()));
        } catch (const InputError&) {
            return std::nullopt;  // a model this build does not know: the default
        }
    }
    return std::nullopt;
}

denoise::NoiseModel stream_noise_model(const std::vector<PointCloud>& views) {
    std::optional<denoise::NoiseModel> found;
    for (const auto& v : views) {
        const auto model = view_noise_model(v);
        if (!model || (found && *found != *model)) return denoise::NoiseModel::kKinectV2;
        found = model;
    }
    return found ? *found : denoise::NoiseModel::kKinectV2;
}

PointCloud load_view(const io::Capture& capture, const std::string& sensor_id, std::size_t position,
                     int view_id, const frames::CloudOptions& cloud_options,
                     const std::optional<Eigen::Vector3d>& centre,
                     const ExtractionOptions& extraction, Report& report) {
    return view_from_frame(io::load_frame(capture, sensor_id, position), view_id, cloud_options,
                           centre, extraction, report);
}

PointCloud view_from_frame(const RgbdFrame& frame, int view_id,
                           const frames::CloudOptions& cloud_options,
                           const std::optional<Eigen::Vector3d>& centre,
                           const ExtractionOptions& extraction, Report& report) {
    // The points the colour camera did not see are coloured once the view is cut to the
    // subject (colour_hidden_points, run by extract_stage).
    frames::CloudOptions options = cloud_options;
    options.colour_hidden = false;
    PointCloud cloud = frames::depth_to_cloud(frame, options, &report);
    cloud.view.id = view_id;
    cloud.view.frame_index = frame.frame_index;
    if (const auto model = frame_noise_model(frame))
        cloud.view.extra_comments.push_back(kNoiseKey + denoise::to_string(*model));
    report["view"] = view_id;
    report["sensor"] = frame.sensor_id;
    report["frame_index"] = frame.frame_index;
    report["points_in_window"] = cloud.size();
    if (centre && extraction.crop_radius_m > 0)
        report["crop"] = frames::crop_to_sphere(cloud, *centre, extraction.crop_radius_m);
    report["points"] = cloud.size();
    return cloud;
}

void SubjectStageOptions::check() const {
    RGBD_CHECK(std::isfinite(crop_radius_m) && crop_radius_m >= 0,
               "crop radius must be >= 0 m, got " + std::to_string(crop_radius_m));
    subject.check();
}

void colour_hidden_points(std::vector<PointCloud>& views) {
    const Rgb fallback = frames::CloudOptions{}.fallback_color;
    tbb::parallel_for(std::size_t(0), views.size(),
                      [&](std::size_t v) { frames::colour_uncoloured(views[v], fallback); });
}

Report extract_stage(std::vector<PointCloud>& views, const std::optional<Eigen::Vector3d>& centre,
                     const SubjectStageOptions& options, const Progress& progress,
                     std::vector<Eigen::Vector3d>* removed_world) {
    options.check();
    if (!options.enabled || views.empty()) {
        colour_hidden_points(views);
        return Report();
    }
    segment::SubjectOptions subject = options.subject;
    subject.crop_radius_m = options.crop_radius_m;
    subject.crop_centre = centre;
    const denoise::NoiseModel fallback = stream_noise_model(views);
    std::vector<denoise::NoiseModel> noise;
    for (const auto& v : views) noise.push_back(view_noise_model(v).value_or(fallback));
    Report report =
        segment::extract_subject(views, noise, subject, /*mark=*/false, progress, removed_world);
    colour_hidden_points(views);
    return report;
}

namespace {

/// Normals oriented towards each view's own sensor, for views that have none. Views in
/// parallel: each view's kd-tree build is sequential, so view-level parallelism keeps both
/// cores busy (the normals do not depend on the order).
void ensure_view_normals(std::vector<PointCloud>& views) {
    normals::NormalOptions options;
    options.orientation = normals::NormalOrientation::kAuto;
    tbb::parallel_for(std::size_t{0}, views.size(), [&](std::size_t v) {
        if (!views[v].points.has_normal_map() && views[v].size() >= 3)
            normals::estimate_normals(views[v], options);
    });
}

}  // namespace

Report align_stage(std::vector<PointCloud>& views, const registration::MultiViewOptions& options,
                   const Progress& progress) {
    ensure_view_normals(views);
    const registration::MultiViewResult result =
        registration::align_views(views, options, progress);
    registration::apply_alignment(views, result);
    Report report = result.to_json();
    for (std::size_t i = 0; i < views.size() && i < report["views"].size(); ++i)
        report["views"][i]["sensor"] = views[i].view.sensor;
    return report;
}

namespace {
constexpr const char* kStandKey = "rgbd:stand.plane ";
}  // namespace

StandMode parse_stand_mode(const std::string& name) {
    if (name == "auto") return StandMode::kAuto;
    if (name == "remove") return StandMode::kRemove;
    if (name == "keep") return StandMode::kKeep;
    throw InputError("the stand mode must be auto, remove or keep, not '" + name + "'");
}

bool stand_applies(const std::vector<PointCloud>& views, StandMode mode) {
    bool one_sensor = views.size() >= 3;
    for (const auto& v : views) one_sensor = one_sensor && v.view.sensor == views[0].view.sensor;
    return mode == StandMode::kRemove || (mode == StandMode::kAuto && one_sensor);
}

Report stand_stage(std::vector<PointCloud>& views, StandMode mode,
                   const segment::StandOptions& options, const Progress& progress) {
    if (!stand_applies(views, mode)) return Report();
    std::optional<segment::SupportPlane> plane;
    Report report = segment::remove_stand(views, options, progress, &plane);
    for (auto& v : views) {
        auto& extra = v.view.extra_comments;
        extra.erase(std::remove_if(extra.begin(), extra.end(),
                                   [](const std::string& c) { return c.rfind(kStandKey, 0) == 0; }),
                    extra.end());
        if (!plane) continue;
        char line[200];
        std::snprintf(line, sizeof line, "%s%.17g %.17g %.17g %.17g", kStandKey, plane->normal.x(),
                      plane->normal.y(), plane->normal.z(), plane->offset);
        extra.emplace_back(line);
    }
    return report;
}

std::optional<segment::SupportPlane> stand_plane_of(const std::vector<PointCloud>& views) {
    for (const auto& v : views)
        for (const auto& c : v.view.extra_comments) {
            if (c.rfind(kStandKey, 0) != 0) continue;
            std::istringstream in(c.substr(std::string(kStandKey).size()));
            segment::SupportPlane plane;
            in >> plane.normal.x() >> plane.normal.y() >> plane.normal.z() >> plane.offset;
            RGBD_CHECK(!in.fail() && plane.normal.allFinite() && std::isfinite(plane.offset) &&
                           std::abs(plane.normal.norm() - 1.0) < 1e-6,
                       "view " + std::to_string(v.view.id) + ": '" + c +
                           "' is not a stand plane (nx ny nz offset_m, unit normal)");
            return plane;
        }
    return std::nullopt;
}

std::size_t add_stand_contact(std::vector<PointCloud>& views,
                              const segment::StandOptions& options) {
    const std::optional<segment::SupportPlane> plane = stand_plane_of(views);
    if (!plane) return 0;
    PointCloud contact = segment::contact_points(views, *plane, options);
    const std::size_t n = contact.size();
    if (n > 0) views.push_back(std::move(contact));
    return n;
}

/// The ground evidence of the closure: the source pixels within this many cut margins of their
/// view's ground plane.
constexpr double kGroundEvidenceBand = 2.0;

Mesh mesh_stage(std::vector<PointCloud>&& views,
                const reconstruction::ReconstructionOptions& options, Report& report,
                const Progress& progress) {
    RGBD_CHECK(!views.empty(), "no views to mesh");
    // The sensors' common up tells --watertight where the object stood (its flat base).
    reconstruction::ReconstructionOptions with_up = options;
    if (!with_up.up) {
        std::vector<Pose> sensors;
        for (const auto& view : views)
            if (view.view.world_from_sensor) sensors.push_back(*view.view.world_from_sensor);
        with_up.up = sensors_up(sensors, 0.7);
    }
    // The ground the extraction removed (each view's plane moved by its aligned pose): a base
    // that reaches it lies on it.
    if (!with_up.ground)
        if (const auto ground = segment::world_ground(views)) {
            with_up.ground = Eigen::Vector4d(ground->normal.x(), ground->normal.y(),
                                             ground->normal.z(), ground->offset);
            with_up.ground_margin_m = ground->margin_m;
            report["ground"] = {
                {"normal", {ground->normal.x(), ground->normal.y(), ground->normal.z()}},
                {"offset_m", ground->offset},
                {"margin_m", ground->margin_m}};
        }
    // The measuring sensors, for the closure's check against the space they saw empty.
    if (with_up.watertight && with_up.sensors.empty())
        for (const auto& view : views)
            if (view.view.world_from_sensor && view.view.intrinsics)
                with_up.sensors.push_back({*view.view.world_from_sensor, view.view.intrinsics});
    ensure_view_normals(views);
    for (auto& view : views) to_world_frame(view);
    // The ground the extraction removed around the subject (the floor beside its base, and
    // the subject's own band below the cut), read again from the views' frames: free-space
    // evidence for the closure (within twice each view's cut margin of its ground plane).
    if (with_up.watertight && !with_up.sensors.empty() && with_up.evidence_points.empty()) {
        Eigen::AlignedBox3d box;
        for (const auto& view : views)
            for (auto idx : view.points) box.extend(to_eigen(view.points.point(idx)));
        if (!box.isEmpty()) {
            const double grow = 0.5 * box.sizes().maxCoeff();
            box.min().array() -= grow;
            box.max().array() += grow;
            Stopwatch watch;
            SourceMeasurements source = source_measurements(views, box, kGroundEvidenceBand);
            report["evidence"] = source.to_json();
            report["evidence"]["time_s"] = watch.seconds();
            with_up.evidence_points = std::move(source.points);
        }
    }
    PointCloud merged =
        views.size() == 1 ? std::move(views.front()) : sampling::merge_views(std::move(views));
    if (!merged.points.has_normal_map()) {
        normals::NormalOptions normal_options;
        normal_options.orientation = normals::NormalOrientation::kMst;
        report["normals"] = normals::estimate_normals(merged, normal_options);
    }
    report["input_points"] = merged.size();
    Report reconstruction;
    Mesh mesh = reconstruction::reconstruct_surface(merged, with_up, &reconstruction, progress);
    report["reconstruction"] = reconstruction;
    return mesh;
}

LoadedResult load_result(const std::string& path) {
    RGBD_CHECK_AS(IoError, fs::exists(path), path + ": no such file");
    LoadedResult result;
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".off" || ext == ".obj") {
        result.mesh = io::read_mesh(path);
        return result;
    }
    if (ext != ".ply") {
        result.views.push_back(io::read_point_cloud(path));
        return result;
    }
    std::ifstream in(path, std::ios::binary);
    RGBD_CHECK_AS(IoError, in.good(), path + ": cannot open for reading");
    io::PlyStreamReader reader(in, path);
    io::Document document;
    while (reader.next(document)) {
        if (document.kind == io::DocumentKind::kMesh) {
            RGBD_CHECK(!result.mesh, path + ": more than one mesh document");
            result.mesh = std::move(document.mesh);
        } else {
            result.views.push_back(std::move(document.cloud));
        }
        document = io::Document{};
    }
    RGBD_CHECK(reader.count() > 0, path + ": empty stream (no PLY document)");
    RGBD_CHECK(!(result.mesh && !result.views.empty()),
               path + ": holds both a mesh and point views; evaluate one of them");
    return result;
}

Report evaluate_surface(const LoadedResult& result, const Mesh& reference,
                        const evaluation::MetricOptions& options) {
    if (result.mesh) {
        return evaluation::compare_to_reference(&*result.mesh, nullptr, reference, options)
            .to_json();
    }
    std::vector<PointCloud> views;
    for (const auto& v : result.views) {
        PointCloud copy;
        copy.points = v.points;
        copy.view = v.view;
        to_world_frame(copy);
        views.push_back(std::move(copy));
    }
    const PointCloud merged = sampling::merge_views(std::move(views));
    return evaluation::compare_to_reference(nullptr, &merged, reference, options).to_json();
}

std::map<std::string, Pose> read_sensor_gt_poses(const io::Capture& capture) {
    std::map<std::string, Pose> poses;
    const std::filesystem::path gt = capture.root / "gt" / "world_from_depth.json";
    if (!std::filesystem::exists(gt)) return poses;
    for (const auto& [id, pose] : read_gt_poses(gt.string()))
        if (id.find('/') == std::string::npos) poses.emplace(id, pose);
    return poses;
}

std::map<std::string, Pose> read_gt_poses(const std::string& path) {
    std::ifstream in(path);
    RGBD_CHECK_AS(IoError, in.good(), path + ": cannot open for reading");
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
        throw InputError(path + ": not valid JSON (" + std::string(e.what()) + ")");
    }
    RGBD_CHECK(j.is_object(), path + ": expected an object of sensor ids");
    auto matrix = [&](const nlohmann::json& m, const std::string& key) {
        RGBD_CHECK(m.is_array() && m.size() == 4, path + ": " + key + " is not a 4x4 matrix");
        std::array<double, 16> v{};
        for (int r = 0; r < 4; ++r) {
            RGBD_CHECK(m[r].is_array() && m[r].size() == 4,
                       path + ": " + key + " is not a 4x4 matrix");
            for (int c = 0; c < 4; ++c) {
                RGBD_CHECK(m[r][c].is_number(), path + ": " + key + " has a non-number");
                v[r * 4 + c] = m[r][c].get<double>();
            }
        }
        try {
            return pose_from_4x4(v);
        } catch (const InputError& e) {
            throw InputError(path + ": " + key + ": " + e.what());
        }
    };
    std::map<std::string, Pose> poses;
    for (auto it = j.begin(); it != j.end(); ++it) {
        if (it->is_object()) {
            for (auto f = it->begin(); f != it->end(); ++f)
                poses[it.key() + "/" + f.key()] = matrix(*f, it.key() + "/" + f.key());
        } else {
            poses[it.key()] = matrix(*it, it.key());
        }
    }
    return poses;
}

Report evaluate_poses(const std::vector<PointCloud>& views, const std::string& gt_path,
                      bool remove_gauge) {
    const auto truth = read_gt_poses(gt_path);
    std::map<std::string, Pose> estimated;
    for (const auto& v : views) {
        RGBD_CHECK(v.view.world_from_sensor.has_value(),
                   "view " + std::to_string(v.view.id) + " has no pose to evaluate");
        std::string key = v.view.sensor;
        if (!truth.count(key) && v.view.frame_index)
            key += "/" + std::to_string(*v.view.frame_index);
        RGBD_CHECK(truth.count(key), gt_path + ": no true pose for view " +
                                         std::to_string(v.view.id) + " (" + key + ")");
        estimated[key] = *v.view.world_from_sensor;
    }
    std::map<std::string, Pose> truth_subset;
    for (const auto& [key, pose] : estimated) truth_subset[key] = truth.at(key);
    return evaluation::pose_errors(estimated, truth_subset, remove_gauge).to_json();
}

}  // namespace rgbd::pipeline
