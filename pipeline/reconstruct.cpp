#include "pipeline/reconstruct.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>

#include "algorithms/evaluation/mesh_quality.hpp"
#include "toolkit/error.hpp"

namespace rgbd::pipeline {

namespace {

/// Points in a set of views.
std::size_t count_points(const std::vector<PointCloud>& views) {
    std::size_t n = 0;
    for (const auto& v : views) n += v.size();
    return n;
}

/// A stage's progress: stage_begin on construction, stage_end on destruction.
class StageScope {
public:
    StageScope(const ReconstructHooks& hooks, std::string stage)
        : hooks_(hooks), stage_(std::move(stage)) {
        if (hooks_.stage_begin) progress_ = hooks_.stage_begin(stage_);
    }
    ~StageScope() {
        if (hooks_.stage_end) hooks_.stage_end(stage_);
    }
    StageScope(const StageScope&) = delete;
    StageScope& operator=(const StageScope&) = delete;
    const Progress& progress() const { return progress_; }

private:
    const ReconstructHooks& hooks_;
    std::string stage_;
    Progress progress_;
};

/// Appends a row to the stages table.
void add_stage(ReconstructResult& result, const std::string& name, double seconds, std::size_t in,
               std::size_t out, Report extra = Report::object()) {
    result.stages.push_back({name, seconds, in, out, std::move(extra)});
}

/// Hands the views after stage number `index` to the front end, if it asked for them.
void views_after(const ReconstructHooks& hooks, int index, const std::string& stage,
                 const std::vector<PointCloud>& views) {
    if (hooks.views_after) hooks.views_after(index, stage, views);
}

/// The views of stages 1-3 and what the stages table needs of them.
struct CloudViews {
    std::vector<PointCloud> views;
    double clean_time = 0, upsample_time = 0, extract_time = 0;
    std::size_t cloud_points = 0, extracted_points = 0, clean_points = 0, upsample_views = 0;
};

/// Runs body(i) for i in [0, n) in parallel (the views are independent) and then rethrows the
/// exception of the lowest i that threw, if any: the same error whatever the threads' order.
/// `progress` gets done / n (scaled into [from, to]) from one thread at a time.
template <class Body>
void for_each_view(std::size_t n, const Progress& progress, double from, double to,
                   const Body& body) {
    std::vector<std::exception_ptr> errors(n);
    std::atomic<std::size_t> done{0};
    std::mutex progress_mutex;
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
        try {
            body(i);
        } catch (...) {
            errors[i] = std::current_exception();
        }
        const std::size_t so_far = ++done;
        const std::lock_guard<std::mutex> lock(progress_mutex);
        report_progress(progress, from + (to - from) * static_cast<double>(so_far) / n);
    });
    for (const auto& e : errors)
        if (e) std::rethrow_exception(e);
}

/// 1a. One coloured cloud per frame (its report in view_reports), without extraction, the
/// frames loaded and converted in parallel; they stay loaded in `loaded` for the
/// super-resolution.
void load_views(const io::Capture& capture, const std::vector<FrameRef>& frames,
                const ReconstructOptions& options, const std::optional<Eigen::Vector3d>& centre,
                const Progress& progress, CloudViews& cv, std::vector<RgbdFrame>& loaded,
                std::vector<Report>& view_reports) {
    const std::size_t n = frames.size();
    loaded.resize(n);
    cv.views.resize(n);
    view_reports.resize(n);
    for_each_view(n, progress, 0.0, 0.5, [&](std::size_t i) {
        loaded[i] = io::load_frame(capture, frames[i].first, frames[i].second);
        cv.views[i] = view_from_frame(loaded[i], static_cast<int>(i), options.cloud, centre,
                                      /*extraction=*/{0.0}, view_reports[i]);
    });
    cv.cloud_points = count_points(cv.views);
}

/// 1b. The object extraction over all views (report["extraction"], its note a warning); the
/// points it removed go to result.removed. InputError prefixed with the capture's root.
void extract_subject(const std::optional<Eigen::Vector3d>& centre,
                     const ReconstructOptions& options, const ReconstructHooks& hooks,
                     const std::string& root, CloudViews& cv, ReconstructResult& result) {
    Report& report = result.report;
    Stopwatch extract_watch;
    try {
        report["extraction"] =
            extract_stage(cv.views, centre, options.extraction, {}, &result.removed);
    } catch (const InputError& e) {
        throw InputError(root + ": " + e.what());
    }
    if (report["extraction"].contains("note") && hooks.warn)
        hooks.warn(report["extraction"]["note"].get<std::string>());
    cv.extract_time = extract_watch.seconds();
    cv.extracted_points = count_points(cv.views);
}

/// 2. distance-based cleaning of one view, reported in `v`. InputError naming the capture, view
/// and sensor when fewer than 100 points are left.
void clean_view(PointCloud& cloud, const RgbdFrame& frame, const ReconstructOptions& options,
                const std::string& root, Report& v) {
    v["points"] = cloud.size();
    // The noise model: the option, else the one the view's sensor names (the stream's
    // metadata, as rgbd-clean --noise-model auto reads it down the pipe).
    denoise::DistanceOptions distance_options = options.distance;
    distance_options.noise_model =
        options.noise_model ? *options.noise_model
                            : view_noise_model(cloud).value_or(denoise::NoiseModel::kKinectV2);
    if (!options.skip.count("distance"))
        v["distance"] = denoise::remove_distance_outliers(cloud, distance_options);
    v["points_after_cleaning"] = cloud.size();
    if (cloud.size() < 100)
        throw InputError(root + ": view " + std::to_string(cloud.view.id) + " (" + frame.sensor_id +
                         ") has only " + std::to_string(cloud.size()) + " points of the subject");
}

/// 3. super-resolution of one view where the colour camera has more pixels than the depth one
/// (reported in `v`); returns whether it ran.
bool upsample_one_view(PointCloud& cloud, const RgbdFrame& frame, const ReconstructOptions& options,
                       Report& v) {
    const bool finer_colour = !frame.color.empty() && static_cast<double>(frame.color.total()) >
                                                          static_cast<double>(frame.depth.total());
    if (options.skip.count("upsample") || !finer_colour || !cloud.view.has_grid()) return false;
    v["upsample"] = upsample::upsample_view(cloud, frame, options.upsample);
    return true;
}

/// Stages 1-3 (the "clouds" progress stage): clouds, then the object extraction over all of
/// them, then distance-based cleaning and super-resolution, one view at a time; each view's
/// report goes to report["views"].
CloudViews cloud_views(const io::Capture& capture, const std::vector<FrameRef>& frames,
                       const ReconstructOptions& options, const ReconstructHooks& hooks,
                       ReconstructResult& result) {
    const std::string root = capture.root.string();
    Report& report = result.report;
    CloudViews cv;
    std::vector<RgbdFrame> loaded;
    std::vector<Report> view_reports;
    report["views"] = Report::array();
    StageScope scope(hooks, "clouds");
    const auto centre = object_centre(capture, frames);
    load_views(capture, frames, options, centre, scope.progress(), cv, loaded, view_reports);
    extract_subject(centre, options, hooks, root, cv, result);
    // Cleaning, then super-resolution, each in parallel over the views (each stage's wall time
    // for the stages table).
    const std::size_t n = cv.views.size();
    Stopwatch clean_watch;
    for_each_view(n, scope.progress(), 0.5, 0.75, [&](std::size_t i) {
        clean_view(cv.views[i], loaded[i], options, root, view_reports[i]);
    });
    cv.clean_time = clean_watch.seconds();
    cv.clean_points = count_points(cv.views);
    Stopwatch upsample_watch;
    std::vector<char> upsampled(n, 0);
    for_each_view(n, scope.progress(), 0.75, 1.0, [&](std::size_t i) {
        upsampled[i] = upsample_one_view(cv.views[i], loaded[i], options, view_reports[i]) ? 1 : 0;
    });
    cv.upsample_time = upsample_watch.seconds();
    for (std::size_t i = 0; i < n; ++i) {
        cv.upsample_views += upsampled[i];
        report["views"].push_back(view_reports[i]);
    }
    return cv;
}

/// The stages table's rows of stages 1-3 (`seconds`: their wall-clock time, of which the
/// clouds' row gets what cleaning, upsampling and extraction did not take).
void add_cloud_stages(const CloudViews& cv, double seconds, const ReconstructOptions& options,
                      const ReconstructHooks& hooks, ReconstructResult& result) {
    const auto& skip = options.skip;
    const std::size_t upsampled_points = count_points(cv.views);
    add_stage(result, "clouds", seconds - cv.clean_time - cv.upsample_time - cv.extract_time, 0,
              cv.cloud_points, {{"views", cv.views.size()}});
    if (options.extraction.enabled)
        add_stage(result, "extract", cv.extract_time, cv.cloud_points, cv.extracted_points);
    if (!skip.count("distance"))
        add_stage(result, "distance", cv.clean_time, cv.extracted_points, cv.clean_points);
    if (!skip.count("upsample")) {
        add_stage(result, "upsample", cv.upsample_time, cv.clean_points, upsampled_points,
                  {{"views", cv.upsample_views}});
        if (cv.upsample_views == 0 && hooks.info)
            hooks.info("upsample: no view has a colour camera finer than its depth camera");
    }
}

/// 4. alignment (report["align"]); a warning for every view whose verdict is not PASS.
void register_views(std::vector<PointCloud>& views, const ReconstructOptions& options,
                    const ReconstructHooks& hooks, ReconstructResult& result) {
    Report& report = result.report;
    Stopwatch watch;
    const std::size_t in = count_points(views);
    {
        StageScope scope(hooks, "align");
        report["align"] = align_stage(views, options.align, scope.progress());
    }
    const double align_time = watch.seconds();
    views_after(hooks, 2, "align", views);
    add_stage(result, "align", align_time, in, count_points(views));
    for (const auto& v : report["align"]["views"])
        if (v["verdict"] != "PASS" && hooks.warn)
            hooks.warn("view " + std::to_string(v["view"].get<int>()) + " (" +
                       v["sensor"].get<std::string>() + "): registration " +
                       v["verdict"].get<std::string>());
}

/// 4b. the stand the object stands on (turntable captures: one sensor, many views), when it
/// applies (report["stand"], its note an info); its plane travels in the views' metadata to
/// the mesh stage, as through rgbd-align's pipe.
void remove_stand(std::vector<PointCloud>& views, const ReconstructOptions& options,
                  const ReconstructHooks& hooks, ReconstructResult& result) {
    if (!stand_applies(views, options.stand)) return;
    Report& report = result.report;
    Stopwatch watch;
    const std::size_t in = count_points(views);
    {
        StageScope scope(hooks, "stand");
        report["stand"] =
            stand_stage(views, options.stand, options.stand_options, scope.progress());
    }
    if (report["stand"].contains("note") && hooks.info)
        hooks.info(report["stand"]["note"].get<std::string>());
    add_stage(result, "stand", watch.seconds(), in, count_points(views));
}

/// The views (stops) used, with their registration verdicts from `align_views`.
Report views_used(const std::vector<PointCloud>& views, const Report& align_views) {
    Report used = Report::array();
    for (std::size_t i = 0; i < views.size(); ++i) {
        Report u = {{"view", views[i].view.id}, {"sensor", views[i].view.sensor}};
        if (views[i].view.frame_index) u["frame_index"] = *views[i].view.frame_index;
        if (i < align_views.size() && align_views[i].contains("verdict"))
            u["verdict"] = align_views[i]["verdict"];
        used.push_back(std::move(u));
    }
    return used;
}

/// 5. density-based cleaning over the aligned views (report["density"]).
void clean_by_density(std::vector<PointCloud>& views, const denoise::DensityOptions& options,
                      const ReconstructHooks& hooks, ReconstructResult& result) {
    Stopwatch watch;
    const std::size_t in = count_points(views);
    {
        StageScope scope(hooks, "density");
        result.report["density"] =
            denoise::remove_density_outliers(views, options, scope.progress());
    }
    add_stage(result, "density", watch.seconds(), in, count_points(views));
    views_after(hooks, 3, "density", views);
}

/// 6. hole filling: one more view with the added points (report["fill"], its note a warning).
void fill_holes(std::vector<PointCloud>& views, const ReconstructOptions& options,
                const ReconstructHooks& hooks, ReconstructResult& result) {
    Stopwatch watch;
    const std::size_t in = count_points(views);
    std::vector<PointCloud*> pointers;
    for (auto& v : views) pointers.push_back(&v);
    Report fill_report;
    std::optional<PointCloud> added;
    {
        StageScope scope(hooks, "fill");
        added = fill_stage(pointers, options.fill, fill_report, scope.progress());
    }
    if (fill_report.contains("note") && hooks.warn)
        hooks.warn(fill_report["note"].get<std::string>());
    const std::size_t count = added ? added->size() : 0;
    if (added) views.push_back(std::move(*added));
    result.report["fill"] = fill_report;
    add_stage(result, "fill", watch.seconds(), in, in + count, {{"points_added", count}});
    views_after(hooks, 4, "fill", views);
}

/// 7. merge + mesh (report["mesh"]), consuming the views, then the mesh's quality
/// (report["mesh_quality"]: slivers, folds, spikes, surface far from every input point, grey
/// fill colours; not the self-intersections) against result.input.
void mesh_views(std::vector<PointCloud>&& views, const ReconstructOptions& options,
                const ReconstructHooks& hooks, ReconstructResult& result) {
    Stopwatch watch;
    const std::size_t mesh_in = count_points(views);
    {
        StageScope scope(hooks, "mesh");
        Report mesh_report;
        reconstruction::ReconstructionOptions mesh_options = options.mesh;
        if (hooks.beside_mesh)
            mesh_options.beside_surface = [&hooks, &result] { hooks.beside_mesh(result); };
        result.mesh = mesh_stage(std::move(views), mesh_options, mesh_report, scope.progress());
        result.report["mesh"] = mesh_report;
    }
    add_stage(result, "mesh", watch.seconds(), mesh_in, result.mesh.number_of_vertices(),
              {{"faces", result.mesh.number_of_faces()}});
    // Not the self-intersection count: 0.4 CPU-seconds per 100,000 faces, a tenth of the
    // 10-view job (rgbd-eval counts them; --repair-self-intersections reports them).
    evaluation::MeshQualityOptions quality;
    quality.self_intersections = false;
    result.report["mesh_quality"] =
        evaluation::mesh_quality(result.mesh, &result.input.vertices, quality);
}

}  // namespace

const std::vector<std::string>& optional_stages() {
    static const std::vector<std::string> stages = {"distance", "upsample", "density", "fill"};
    return stages;
}

std::vector<FrameRef> frameset_frames(const io::Capture& capture, std::size_t frameset) {
    const std::string root = capture.root.string();
    std::vector<FrameRef> frames;
    if (capture.framesets.empty()) {
        for (const auto& sensor : capture.rig.sensors) {
            const auto it = capture.frames.find(sensor.id);
            if (it == capture.frames.end()) continue;
            for (std::size_t i = 0; i < it->second.size(); ++i) frames.emplace_back(sensor.id, i);
        }
    } else {
        RGBD_CHECK(frameset < capture.framesets.size(),
                   root + ": frame set " + std::to_string(frameset) + " is out of range (" +
                       std::to_string(capture.framesets.size()) + " frame sets)");
        const io::FrameSet& set = capture.framesets[frameset];
        for (std::size_t s = 0; s < capture.rig.sensors.size() && s < set.frames.size(); ++s) {
            if (set.frames[s] < 0) continue;
            const std::string& id = capture.rig.sensors[s].id;
            const auto position = capture.find_frame(id, set.frames[s]);
            RGBD_CHECK(position.has_value(), root + ": frame set " + std::to_string(frameset) +
                                                 " names frame " + std::to_string(set.frames[s]) +
                                                 " of sensor " + id +
                                                 ", which its frames.csv does not list");
            frames.emplace_back(id, *position);
        }
    }
    RGBD_CHECK(!frames.empty(), root + ": no frames selected");
    return frames;
}

void ReconstructOptions::check() const {
    for (const auto& s : skip)
        RGBD_CHECK(std::find(optional_stages().begin(), optional_stages().end(), s) !=
                       optional_stages().end(),
                   "unknown stage '" + s + "' (valid: distance, upsample, density, fill)");
    extraction.check();
    stand_options.check();
    upsample.check();
    mesh.check();
}

Report ReconstructResult::stages_report() const {
    Report rows = Report::array();
    for (const auto& row : stages) {
        Report r = row.extra;
        r["stage"] = row.stage;
        r["time_s"] = row.time_s;
        r["points_in"] = row.points_in;
        r["points_out"] = row.points_out;
        rows.push_back(std::move(r));
    }
    return rows;
}

Report ReconstructResult::timings() const {
    Report t = Report::object();
    for (const auto& row : stages) t[row.stage] = row.time_s;
    return t;
}

ReconstructResult reconstruct(const io::Capture& capture, const std::vector<FrameRef>& frames,
                              const ReconstructOptions& options, const ReconstructHooks& hooks) {
    options.check();
    const auto& skip = options.skip;
    ReconstructResult result;
    Report& report = result.report;

    // 1. clouds, then the object extraction over all of them, then 2. distance-based cleaning
    // and 3. super-resolution, one view at a time.
    Stopwatch watch;
    CloudViews cv = cloud_views(capture, frames, options, hooks, result);
    add_cloud_stages(cv, watch.seconds(), options, hooks, result);
    std::vector<PointCloud>& views = cv.views;
    // The density cleaning's noise model: the option, else the stream's.
    denoise::DensityOptions density_options = options.density;
    density_options.seed = options.seed;
    density_options.noise_model =
        options.noise_model ? *options.noise_model : stream_noise_model(views);
    report["noise_model"] = denoise::to_string(density_options.noise_model);
    if (hooks.info) hooks.info("clouds: " + std::to_string(views.size()) + " views");
    views_after(hooks, 1, "views", views);

    // 4. alignment, 4b. the stand, and the views used.
    register_views(views, options, hooks, result);
    remove_stand(views, options, hooks, result);
    report["views_used"] = views_used(views, report["align"]["views"]);

    // 5. density-based cleaning over the aligned views.
    if (!skip.count("density")) clean_by_density(views, density_options, hooks, result);

    // The aligned poses for the pose evaluation, before the views are consumed.
    for (const auto& v : views) {
        PointCloud p;
        p.view = v.view;
        result.poses.push_back(std::move(p));
    }

    // 6. hole filling.
    if (!skip.count("fill")) fill_holes(views, options, hooks, result);

    // The object's walls carried down to the stand's plane (cut margin_m above it), so that the
    // closed mesh's flat base lies where the object stood.
    if (report.contains("stand"))
        report["stand"]["contact_points"] = add_stand_contact(views, options.stand_options);

    // The aligned points, for the mesh quality and pictures.
    result.input = render::from_views(views);

    // 7. merge + mesh.
    mesh_views(std::move(views), options, hooks, result);
    report["counts"] = {{"views", result.poses.size()},
                        {"mesh_vertices", result.mesh.number_of_vertices()},
                        {"mesh_faces", result.mesh.number_of_faces()}};
    return result;
}

}  // namespace rgbd::pipeline
