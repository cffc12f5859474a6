// The pipeline stages from Python (docs/python.md): each function maps its keyword options onto
// the stage's option structs exactly as the single tool maps its command line (cli/rgbd_cloud.cpp,
// rgbd_clean.cpp, rgbd_upsample.cpp, rgbd_align.cpp, rgbd_fill.cpp, rgbd_mesh.cpp, rgbd_eval.cpp,
// rgbd_reconstruct.cpp: same names with underscores, same defaults) and calls the same library
// functions, with the GIL released. Views are modified in place, as the pipe would carry them.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/denoise/density_outliers.hpp"
#include "algorithms/denoise/depth_smoothing.hpp"
#include "algorithms/denoise/distance_outliers.hpp"
#include "algorithms/texture/texture_mesh.hpp"
#include "algorithms/upsample/upsample_view.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/textured_mesh_io.hpp"
#include "pipeline/fill_stage.hpp"
#include "pipeline/reconstruct.hpp"
#include "pipeline/stages.hpp"
#include "pipeline/texture_views.hpp"
#include "python/bindings.hpp"
#include "toolkit/error.hpp"

namespace rgbd::python {

io::Capture capture_of(const py::object& capture) {
    if (py::isinstance<io::Capture>(capture)) return capture.cast<io::Capture>();
    const auto path = capture.cast<std::filesystem::path>();
    py::gil_scoped_release release;
    return io::open_capture(path);
}

std::vector<std::pair<std::string, std::size_t>> selected_frames(
    const io::Capture& capture, long long frameset, const std::string& frames,
    const std::vector<std::string>& sensors) {
    try {
        return cli::select_frames(capture, frameset, frames, sensors, nullptr);
    } catch (const cli::UsageError& e) {
        throw InputError(e.what());
    }
}

std::optional<denoise::NoiseModel> noise_model_option(Options& options) {
    std::string name = "auto";
    options.get("noise_model", name);
    if (name == "auto") return std::nullopt;
    try {
        return denoise::parse_noise_model(name);
    } catch (const InputError& e) {
        throw InputError(std::string("noise_model: ") + e.what());
    }
}

namespace {

using namespace pybind11::literals;

/// Runs `one(view, progress)` on every view in turn without the GIL (progress reported as
/// `stage`) and returns their reports, each tagged with its view's id, as a Python list.
template <typename PerView>
py::list reports_per_view(ProgressBridge& bridge, const char* stage,
                          const std::vector<PointCloud*>& views, PerView&& one) {
    std::vector<Report> reports = without_gil(bridge, [&] {
        const Progress progress = bridge.stage(stage);
        std::vector<Report> out;
        for (PointCloud* cloud : views) {
            Report report = one(*cloud, progress);
            report["view"] = cloud->view.id;
            out.push_back(std::move(report));
        }
        return out;
    });
    py::list out;
    for (const auto& r : reports) out.append(to_python(r));
    return out;
}

// ---- clouds -----------------------------------------------------------------------------------

py::object clouds(const py::object& capture_arg, const py::kwargs& kwargs) {
    Options o("clouds", kwargs);
    frames::CloudOptions options;
    pipeline::SubjectStageOptions extraction;
    long long frameset = 0;
    std::string frames;
    std::vector<std::string> sensors;
    o.get("frameset", frameset);
    o.get("frames", frames);
    o.get("sensors", sensors);
    o.get("z_min", options.z_min_m);
    o.get("z_max", options.z_max_m);
    options.use_mask = !o.flag("no_mask");
    o.get("crop_radius_m", extraction.crop_radius_m);
    extraction.subject.remove_ground = !o.flag("keep_ground");
    extraction.enabled = !o.flag("no_extract");
    ProgressBridge bridge(o.object("progress"));
    o.done();
    check_range("z_min", options.z_min_m, Range::closed(0, 100), "m");
    check_range("z_max", options.z_max_m, Range::closed(0, 100), "m");
    check_range("crop_radius_m", extraction.crop_radius_m, Range::closed(0, 100), "m");
    options.check();
    std::sort(sensors.begin(), sensors.end());  // rgbd-cloud --sensors: a set of ids
    sensors.erase(std::unique(sensors.begin(), sensors.end()), sensors.end());

    const io::Capture capture = capture_of(capture_arg);
    const auto jobs = selected_frames(capture, frameset, frames, sensors);
    std::vector<PointCloud> views = without_gil(bridge, [&] {
        const Progress progress = bridge.stage("clouds");
        const auto centre = pipeline::object_centre(capture, jobs);
        std::vector<PointCloud> out;
        for (const auto& [id, position] : jobs) {
            Report report;
            out.push_back(pipeline::load_view(capture, id, position, static_cast<int>(out.size()),
                                              options, centre, /*extraction=*/{0.0}, report));
            report_progress(progress, 0.8 * out.size() / jobs.size());
        }
        try {
            pipeline::extract_stage(out, centre, extraction);
        } catch (const InputError& e) {
            throw InputError(capture.root.string() + ": " + e.what());
        }
        report_progress(progress, 1.0);
        return out;
    });
    return py::cast(std::move(views));
}

// ---- clean_distance / clean_density -----------------------------------------------------------

py::object clean_distance(const py::handle& views_arg, const py::kwargs& kwargs) {
    Options o("clean_distance", kwargs);
    const auto views = views_of(views_arg, "clean_distance");
    denoise::DistanceOptions distance;
    denoise::SmoothOptions smoothing;
    const auto noise = noise_model_option(o);
    o.get("k", distance.k);
    o.get("theta_max_deg", distance.theta_max_deg);
    // high_recall sets its operating point; options given explicitly still win.
    if (o.flag("high_recall")) distance.use_high_recall();
    o.get("c_min", distance.c_min);
    o.get("line_sigmas", distance.line_sigmas);
    o.get("dense_min", distance.dense_min);
    o.get("c_min_wide", distance.c_min_wide);
    o.get("keep_knn", distance.keep_knn);
    o.get("keep_k", distance.keep_k);
    o.get("n_speckle", distance.n_speckle);
    o.get("alpha", distance.alpha);
    distance.pass_a = !o.flag("no_pass_a");
    distance.pass_b = o.flag("knn_test");
    distance.mark = o.flag("mark");
    const bool smooth = o.flag("smooth");
    ProgressBridge bridge(o.object("progress"));
    o.done();
    if (noise) distance.noise_model = smoothing.noise_model = *noise;
    distance.check();
    smoothing.check();

    return reports_per_view(
        bridge, "clean_distance", views, [&](PointCloud& cloud, const Progress& progress) {
            if (!noise)
                distance.noise_model = smoothing.noise_model =
                    pipeline::view_noise_model(cloud).value_or(denoise::NoiseModel::kKinectV2);
            Report report = denoise::remove_distance_outliers(cloud, distance, progress);
            if (smooth) report["smooth"] = denoise::smooth_depth(cloud, smoothing);
            return report;
        });
}

py::object clean_density(const py::handle& views_arg, const py::kwargs& kwargs) {
    Options o("clean_density", kwargs);
    const auto views = views_of(views_arg, "clean_density");
    denoise::DensityOptions density;
    const auto noise = noise_model_option(o);
    o.get("k", density.k);
    o.get("theta_max_deg", density.theta_max_deg);
    double beta = 0;
    if (o.get("beta", beta)) density.beta = density.beta_local = beta;
    std::string reference = "auto";
    o.get("reference", reference);
    const auto parsed = denoise::density_reference_of(reference);
    if (!parsed)
        throw InputError("reference must be auto, sensors or local, not '" + reference + "'");
    density.reference = *parsed;
    o.get("consensus_ratio", density.consensus_ratio);
    o.get("consensus_sigmas", density.consensus_sigmas);
    o.get("cluster_spacing", density.cluster_spacing);
    o.get("min_cluster_fraction", density.min_cluster_fraction);
    density.judge_synthetic = o.flag("judge_synthetic");
    density.seed = 0;  // the tools' --seed default
    o.get("seed", density.seed);
    density.mark = o.flag("mark");
    ProgressBridge bridge(o.object("progress"));
    o.done();
    density.check();

    const Report report = without_gil(bridge, [&] {
        BorrowedViews borrowed(views);
        density.noise_model = noise ? *noise : pipeline::stream_noise_model(borrowed.views());
        return denoise::remove_density_outliers(borrowed.views(), density,
                                                bridge.stage("clean_density"));
    });
    return to_python(report);
}

// ---- upsample ---------------------------------------------------------------------------------

std::string view_label(const PointCloud& cloud) {
    std::string label = "view " + std::to_string(cloud.view.id);
    if (!cloud.view.source.empty()) label += " (" + cloud.view.source + ")";
    return label;
}

py::object upsample(const py::handle& views_arg, const py::object& capture_arg,
                    const py::kwargs& kwargs) {
    Options o("upsample", kwargs);
    const auto views = views_of(views_arg, "upsample");
    upsample::UpsampleOptions options;
    o.get("neighbors", options.neighbors);
    if (o.flag("midpoints")) options.method = upsample::UpsampleMethod::kMidpoints;
    o.get("sigma_spatial", options.sigma_spatial);
    o.get("sigma_color", options.sigma_color);
    o.get("grazing_deg", options.grazing_max_deg);
    o.get("theta_max_deg", options.theta_max_deg);
    ProgressBridge bridge(o.object("progress"));
    o.done();
    options.check();
    const io::Capture capture = capture_of(capture_arg);

    // As rgbd-upsample per view: the view's frame in the capture, then upsample_view.
    return reports_per_view(
        bridge, "upsample", views, [&](PointCloud& view, const Progress& progress) -> Report {
            PointCloud* cloud = &view;
            RGBD_CHECK(cloud->view.has_grid(),
                       view_label(*cloud) +
                           ": the view has no pixel grid (rgbd:grid); upsample needs organised "
                           "views from clouds()");
            if (cloud->empty()) return {{"note", "no points"}};
            RGBD_CHECK(cloud->view.frame_index,
                       view_label(*cloud) + ": no rgbd:view.frame_index to find its frame");
            std::string sensor = cloud->view.sensor;
            if (sensor.empty() && capture.rig.sensors.size() == 1)
                sensor = capture.rig.sensors[0].id;
            const auto position = capture.find_frame(sensor, *cloud->view.frame_index);
            RGBD_CHECK(position, view_label(*cloud) + ": frame " +
                                     std::to_string(*cloud->view.frame_index) + " of sensor '" +
                                     sensor + "' is not in capture " + capture.root.string());
            const io::FrameRecord& record = capture.frames.at(sensor)[*position];
            RGBD_CHECK(!record.color.empty(), view_label(*cloud) + ": frame " +
                                                  std::to_string(record.index) + " of sensor '" +
                                                  sensor + "' has no colour image in capture " +
                                                  capture.root.string());
            const RgbdFrame frame = io::load_frame(capture, sensor, *position);
            return upsample::upsample_view(*cloud, frame, options, progress);
        });
}

// ---- align ------------------------------------------------------------------------------------

py::object align(const py::handle& views_arg, const py::kwargs& kwargs) {
    Options o("align", kwargs);
    const auto views = views_of(views_arg, "align");
    registration::MultiViewOptions options;
    int fixed_view = 0;
    o.get("fixed_view", fixed_view);
    RGBD_CHECK(fixed_view >= 0, "fixed_view must be >= 0");
    options.fixed_view = static_cast<std::size_t>(fixed_view);
    o.get("rounds", options.rounds);
    o.get("voxel_m", options.voxel_m);
    options.pairwise = !o.flag("no_pairwise");
    options.global_registration = !o.flag("no_global");
    o.get("colour_weight", options.colour_weight);
    o.get("ransac_iterations", options.ransac_iterations);
    o.get("max_prior_rotation_deg", options.max_prior_rotation_deg);
    options.seed = 0;  // the tools' --seed default
    o.get("seed", options.seed);
    std::string stand_name = "auto";
    o.get("stand", stand_name);
    const bool ignore_poses = o.flag("ignore_poses");
    ProgressBridge bridge(o.object("progress"));
    o.done();
    options.check();
    const pipeline::StandMode stand = pipeline::parse_stand_mode(stand_name);
    RGBD_CHECK(options.fixed_view < views.size(),
               "fixed_view " + std::to_string(options.fixed_view) + " but there are " +
                   std::to_string(views.size()) + " views");

    const Report report = without_gil(bridge, [&] {
        BorrowedViews borrowed(views);
        auto& all = borrowed.views();
        if (ignore_poses)
            for (PointCloud& view : all) {
                if (view.view.frame == ViewFrame::kWorld && view.view.world_from_sensor)
                    transform(view, view.view.world_from_sensor->inverse());
                view.view.frame = ViewFrame::kSensor;
                view.view.world_from_sensor = Pose::Identity();
            }
        Report out;
        out["align"] = pipeline::align_stage(all, options, bridge.stage("align"));
        if (pipeline::stand_applies(all, stand))
            out["stand"] =
                pipeline::stand_stage(all, stand, segment::StandOptions{}, bridge.stage("stand"));
        return out;
    });
    return to_python(report);
}

// ---- fill -------------------------------------------------------------------------------------

pipeline::FillStageOptions fill_options(Options& o) {
    pipeline::FillStageOptions stage;
    holes::BoundaryOptions& detect = stage.detect;
    holes::FillOptions& fill = stage.fill;
    holes::InpaintOptions& inpaint = stage.inpaint;
    o.get("k", detect.neighbourhood.k);
    o.get("radius_factor", detect.neighbourhood.radius_factor);
    if (o.get("spacing_m", detect.spacing_m))
        RGBD_CHECK(detect.spacing_m > 0, "spacing_m must be a positive number");
    o.get("threshold", detect.threshold);
    std::vector<double> weights;
    if (o.get("weights", weights)) {
        RGBD_CHECK(weights.size() == 3, "weights needs three numbers A, H, S");
        detect.w_angle = weights[0];
        detect.w_halfdisk = weights[1];
        detect.w_shape = weights[2];
    }
    o.get("coherence", detect.coherence_passes);
    detect.coherence_both = o.flag("coherence_both");
    o.get("hysteresis", detect.hysteresis_threshold);
    o.get("hysteresis_rings", detect.hysteresis_rings);
    o.get("min_loop", detect.min_loop_points);
    o.get("small_diameter", detect.small_max_diameter);
    o.get("small_points", detect.small_max_points);
    o.get("visible_angle_deg", detect.visible_max_angle_deg);
    std::string mechanism;
    if (o.get("mechanism", mechanism)) fill.mechanism = holes::parse_fill_mechanism(mechanism);
    o.get("step", fill.step);
    o.get("max_sweeps", fill.max_sweeps);
    o.get("max_fit_rms", fill.max_fit_rms);
    fill.fill_openings = o.flag("fill_openings");
    o.get("inpaint_pixel", inpaint.pixel);
    o.get("telea_radius", inpaint.telea_radius);
    std::string colour = "criminisi";
    o.get("colour_inpaint", colour);
    if (colour == "criminisi")
        inpaint.colour = holes::ColourInpaint::kCriminisi;
    else if (colour == "telea")
        inpaint.colour = holes::ColourInpaint::kTelea;
    else
        throw InputError("colour_inpaint must be criminisi or telea, not '" + colour + "'");
    o.get("patch", inpaint.patch);
    o.get("search_window", inpaint.search_window);
    o.get("top_fraction", inpaint.top_fraction);
    o.get("top_min_up", inpaint.top_min_up);
    o.get("top_fit_radii", inpaint.top_fit_radii);
    inpaint.ellipsoid = !o.flag("no_ellipsoid");
    o.get("max_ellipsoid_rms", inpaint.max_ellipsoid_rms);
    inpaint.biharmonic = !o.flag("no_biharmonic");
    o.get("max_biharmonic_slope", inpaint.max_biharmonic_slope);
    o.get("max_open_rim", inpaint.max_open_rim);
    inpaint.top_without_ellipsoid = o.flag("top_without_ellipsoid");
    o.get("min_rim_radial", inpaint.min_rim_radial);
    o.get("clearance", inpaint.clearance);
    inpaint.carve = !o.flag("no_carve");
    o.get("carve_margin", inpaint.free_space.margin);
    o.get("max_contradicted", inpaint.max_contradicted);
    inpaint.visible_max_angle_deg = detect.visible_max_angle_deg;
    inpaint.fill_openings = fill.fill_openings;
    stage.detect_only = o.flag("detect_only");
    stage.mark = o.flag("mark");
    stage.large = !o.flag("no_large");
    stage.head_top = !o.flag("no_head_top");
    stage.ignore_poses = o.flag("ignore_poses");
    stage.debug_colors = o.flag("debug_colors");
    long long max_points = static_cast<long long>(stage.max_points);
    o.get("max_points", max_points);
    RGBD_CHECK(max_points >= 0, "max_points must be 0 or more");
    stage.max_points = static_cast<std::size_t>(max_points);
    detect.check();
    fill.check();
    inpaint.check();
    return stage;
}

py::object fill(py::list views_arg, const py::kwargs& kwargs) {
    Options o("fill", kwargs);
    const auto views = views_of(views_arg, "fill");
    const pipeline::FillStageOptions stage = fill_options(o);
    ProgressBridge bridge(o.object("progress"));
    o.done();
    Report report;
    std::optional<PointCloud> added = without_gil(
        bridge, [&] { return pipeline::fill_stage(views, stage, report, bridge.stage("fill")); });
    // As rgbd-fill: the added points follow the views as one more view.
    if (added) views_arg.append(py::cast(std::move(*added)));
    return to_python(report);
}

// ---- mesh -------------------------------------------------------------------------------------

reconstruction::ReconstructionOptions mesh_options(Options& o, bool watertight) {
    reconstruction::ReconstructionOptions options;
    o.get("method", options.method);
    long long max_points = static_cast<long long>(options.max_points);
    long long target_faces = 0;
    o.get("max_points", max_points);
    o.get("target_faces", target_faces);
    RGBD_CHECK(max_points >= 0, "max_points must be >= 0, got " + std::to_string(max_points));
    RGBD_CHECK(target_faces >= 0,
               "target_faces must be 0 (keep) or >= 4, got " + std::to_string(target_faces));
    options.max_points = static_cast<std::size_t>(max_points);
    options.target_faces = static_cast<std::size_t>(target_faces);
    options.watertight = watertight;
    if (o.flag("no_carve_closure")) options.carve_steps = 0;
    options.repair_self_intersections = o.flag("repair_self_intersections");
    options.check();
    return options;
}

py::object mesh(const py::handle& views_arg, const py::kwargs& kwargs) {
    Options o("mesh", kwargs);
    const auto views = views_of(views_arg, "mesh");
    const bool watertight = o.flag("watertight");
    const auto options = mesh_options(o, watertight);
    ProgressBridge bridge(o.object("progress"));
    o.done();
    Report report;
    Mesh result = without_gil(bridge, [&] {
        // The mesher consumes its views: a copy, so the caller's stay as they are.
        std::vector<PointCloud> copies;
        for (const PointCloud* v : views) copies.push_back(*v);
        // A stand removed by align(): the object's walls carried down to its plane.
        const std::size_t contact = pipeline::add_stand_contact(copies);
        if (contact > 0) report["stand_contact_points"] = contact;
        return pipeline::mesh_stage(std::move(copies), options, report, bridge.stage("mesh"));
    });
    py::object out = py::cast(std::move(result));
    out.attr("report") = to_python(report);
    return out;
}

}  // namespace

void bind_stages(py::module_& m) {
    m.def("clouds", &clouds, "capture"_a,
          "Views from a capture (rgbd-cloud): the frames of one frame set (multi-sensor) or "
          "every frame (single-sensor sequences) as coloured clouds in the sensor frame, then "
          "the object extraction over all of them. `capture` is a Capture or a path. Options "
          "(rgbd-cloud's): frameset=0, frames='A:B[:STEP]', sensors=[ids], z_min=0, z_max=0 "
          "(metres, 0 = the sensor's range), no_mask=False, crop_radius_m=0, keep_ground=False, "
          "no_extract=False, progress=None. Returns a list of PointCloud.");
    m.def("clean_distance", &clean_distance, "views"_a,
          "Distance-based noise removal per organised view, in place (rgbd-clean --distance). "
          "Options: noise_model='auto' (each view's own, else kinect_v2), k, theta_max_deg, "
          "c_min, c_min_wide, line_sigmas, dense_min, keep_knn, keep_k, n_speckle, alpha, "
          "no_pass_a, knn_test, high_recall, mark, smooth, progress (defaults: rgbd-clean's). "
          "Returns one report dict per view.");
    m.def("upsample", &upsample, "views"_a, "capture"_a,
          "Colour-guided super-resolution of every organised view, in place (rgbd-upsample), "
          "with the frames of `capture` (a Capture or a path). Options: neighbors=8, "
          "midpoints=False, sigma_spatial, sigma_color, grazing_deg, theta_max_deg, progress. "
          "Returns one report dict per view.");
    m.def("align", &align, "views"_a,
          "Multi-view registration, in place (rgbd-align without --merge): the views end in the "
          "world frame with their refined poses; then the stand below the object (stand='auto', "
          "'remove' or 'keep'). Options: fixed_view=0, rounds, voxel_m, no_pairwise, no_global, "
          "colour_weight, ransac_iterations, max_prior_rotation_deg, seed=0, stand='auto', "
          "ignore_poses=False, progress. Returns the report dict {'align': ..., 'stand': ...}.");
    m.def("clean_density", &clean_density, "views"_a,
          "Density-based noise removal over all aligned views, in place (rgbd-clean --density). "
          "Options: noise_model='auto', k, theta_max_deg, beta, reference='auto', "
          "consensus_ratio, consensus_sigmas, cluster_spacing, min_cluster_fraction, "
          "judge_synthetic, seed=0, mark, progress. Returns the report dict.");
    m.def("fill", &fill, "views"_a,
          "Hole filling on aligned views (rgbd-fill): appends the added points to the list "
          "`views` as one more view (nothing when no hole was filled). Options: rgbd-fill's "
          "(mechanism='interpolation', k, radius_factor, spacing_m, threshold, "
          "weights=(0.4, 0.4, 0.2), min_loop, small_diameter, detect_only, mark, no_large, "
          "no_head_top, ignore_poses, max_points, ... with underscores), progress. Returns the "
          "report dict.");
    m.def("mesh", &mesh, "views"_a,
          "Surface reconstruction of the views (rgbd-mesh; the views are not modified). "
          "Options: method='front', max_points, watertight=False, no_carve_closure=False, "
          "target_faces=0, progress. "
          "Returns a Mesh whose `report` attribute holds the stage's report.");
}

}  // namespace rgbd::python
