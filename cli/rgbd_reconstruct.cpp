// rgbd-reconstruct: the whole method on a capture folder with defaults, a mesh and a report.
// The chain is the README's pipe, stage for stage, with the same defaults (a test checks that
// both give the same mesh):
//   rgbd-cloud | rgbd-clean --distance | rgbd-upsample | rgbd-align | rgbd-clean --density
//     | rgbd-fill | rgbd-mesh --watertight
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "algorithms/denoise/density_outliers.hpp"
#include "algorithms/denoise/distance_outliers.hpp"
#include "algorithms/evaluation/mesh_quality.hpp"
#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/render/picture.hpp"
#include "algorithms/upsample/upsample_view.hpp"
#include "cli/common/fill_stage.hpp"
#include "cli/common/report_page.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

/// The stages --skip can leave out, in the order they run.
const std::vector<std::string> kOptionalStages = {"distance", "upsample", "density", "fill"};

/// Parses --skip "a,b": the stage names, each one of kOptionalStages.
std::set<std::string> parse_skip(const std::string& text) {
    std::set<std::string> skip;
    std::stringstream in(text);
    std::string name;
    std::string valid;
    for (const auto& s : kOptionalStages) valid += (valid.empty() ? "" : ", ") + s;
    while (std::getline(in, name, ',')) {
        if (name.empty()) continue;
        if (std::find(kOptionalStages.begin(), kOptionalStages.end(), name) ==
            kOptionalStages.end())
            throw cli::UsageError("--skip: unknown stage '" + name + "' (valid: " + valid + ")");
        skip.insert(name);
    }
    return skip;
}

/// Points in a set of views.
std::size_t count_points(const std::vector<PointCloud>& views) {
    std::size_t n = 0;
    for (const auto& v : views) n += v.size();
    return n;
}

/// The noise model of the rig's sensors (their noise.model, else their model) when they all
/// agree on one the denoisers know, else Kinect v2 (rgbd-clean's default).
denoise::NoiseModel rig_noise_model(const io::Rig& rig, bool* from_rig) {
    std::optional<denoise::NoiseModel> found;
    *from_rig = false;
    for (const auto& sensor : rig.sensors) {
        std::optional<denoise::NoiseModel> model;
        for (const std::string& name : {sensor.noise_model, sensor.model}) {
            if (name.empty() || model) continue;
            try {
                model = denoise::parse_noise_model(name);
            } catch (const InputError&) {
            }
        }
        if (!model || (found && *found != *model)) return denoise::NoiseModel::kKinectV2;
        found = model;
    }
    if (!found) return denoise::NoiseModel::kKinectV2;
    *from_rig = true;
    return *found;
}

/// Writes the views after a stage as a view stream, DIR/NN-stage.ply (atomically), when DIR is
/// given (--stages-dir): the same documents the pipe carries between the single tools.
void save_stage(const std::optional<fs::path>& dir, int index, const std::string& stage,
                const std::vector<PointCloud>& views) {
    if (!dir) return;
    std::ostringstream out;
    for (const auto& view : views) io::write_points(out, view);
    const std::string bytes = out.str();
    char name[64];
    std::snprintf(name, sizeof name, "%02d-%s.ply", index, stage.c_str());
    io::write_bytes_atomic(*dir / name, reinterpret_cast<const std::uint8_t*>(bytes.data()),
                           bytes.size());
}

/// One row of the stages table: what ran, how long, points in and out.
struct StageLog {
    Report rows = Report::array();
    void add(const std::string& name, double seconds, std::size_t in, std::size_t out,
             Report extra = Report::object()) {
        extra["stage"] = name;
        extra["time_s"] = seconds;
        extra["points_in"] = in;
        extra["points_out"] = out;
        rows.push_back(std::move(extra));
    }
};

/// The report page: pictures (input, mesh, heat map), evaluation, stages, views.
cli::ReportPage report_page(const Report& report) {
    cli::ReportPage page;
    page.title = "rgbd-reconstruct";
    page.facts = {{"capture", report["capture"].get<std::string>()},
                  {"mesh", report["mesh_file"].get<std::string>()}};
    std::string skipped;
    for (const auto& s : report["skipped_stages"])
        skipped += (skipped.empty() ? "" : ", ") + s.get<std::string>();
    page.facts.push_back({"stages skipped", skipped.empty() ? "none" : skipped});
    if (report.contains("evaluation"))
        page.tables.push_back(
            cli::side_by_side("Against the ground truth", {{"result", report["evaluation"]}}));
    if (report.contains("mesh_quality"))
        page.tables.push_back(
            cli::side_by_side("Mesh quality", {{"result", report["mesh_quality"]}}));
    cli::ReportTable stages;
    stages.heading = "Stages";
    stages.columns = {"stage", "time (s)", "points in", "points out"};
    for (const auto& s : report["stages"])
        stages.rows.push_back({s["stage"].get<std::string>(), cli::format_value(s["time_s"]),
                               s["points_in"].dump(), s["points_out"].dump()});
    page.tables.push_back(stages);
    cli::ReportTable views;
    views.heading = "Views";
    views.columns = {"view",    "sensor",  "points",   "after cleaning",
                     "verdict", "fitness", "rmse (mm)"};
    for (const auto& v : report["align"]["views"]) {
        const int id = v["view"].get<int>();
        views.rows.push_back({std::to_string(id), v["sensor"].get<std::string>(),
                              report["views"][id]["points"].dump(),
                              report["views"][id]["points_after_cleaning"].dump(),
                              v["verdict"].get<std::string>(), cli::format_value(v["fitness"]),
                              cli::format_value(Report(v["inlier_rmse_m"].get<double>() * 1000))});
    }
    page.tables.push_back(views);
    return page;
}

}  // namespace

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-reconstruct";
    spec.usage =
        "rgbd-reconstruct CAPTURE_DIR -o MESH [--report DIR] [--skip STAGE[,STAGE]] [options]";
    spec.description =
        "Runs the whole method on a capture folder with the defaults of each stage, in the order "
        "of the README's pipe: coloured clouds per view (rgbd-cloud), adaptive distance-based "
        "noise removal per view (rgbd-clean --distance), colour-guided super-resolution "
        "(rgbd-upsample, 8 neighbours; only for sensors whose colour camera has more pixels than "
        "the depth camera), multi-view registration from the rig's poses (rgbd-align), adaptive "
        "density-based noise removal over the aligned views (rgbd-clean --density), hole "
        "filling (rgbd-fill: small holes, head top, large holes, only where no sensor saw the "
        "surface) and surface reconstruction (rgbd-mesh --watertight: a closed coloured mesh; "
        "--open keeps unseen holes). The same options through the pipe give the same mesh. "
        "--skip leaves stages out (distance, upsample, density, fill) for comparisons. Writes "
        "the mesh and a report folder (metrics.json and index.html) with each stage's time and "
        "point counts in and out, per-view registration verdicts, the mesh's quality and, when "
        "the capture has ground truth (gt/ of rgbd-synth) or --reference is given, the metrics "
        "of rgbd-eval.";
    spec.example = "rgbd-reconstruct cap/ -o bust.ply --report report/";
    spec.reads_stream = false;
    spec.writes_stream = false;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("report", cli::po::value<std::string>()->value_name("DIR"),
                        "report folder (default: MESH without extension + _report)")(
            "frameset", cli::po::value<long long>()->default_value(0)->value_name("N"),
            "frame set to reconstruct (multi-sensor captures)")(
            "frames", cli::po::value<std::string>()->value_name("A:B[:STEP]"),
            "frame positions (single-sensor sequences; default all)")(
            "reference", cli::po::value<std::string>()->value_name("MESH"),
            "reference surface for the evaluation (default: CAPTURE/gt/mesh.ply if present)")(
            "skip", cli::po::value<std::string>()->value_name("STAGE[,STAGE]"),
            "leave stages out of the chain: distance, upsample, density, fill")(
            "stages-dir", cli::po::value<std::string>()->value_name("DIR"),
            "also write the views after each stage to DIR/NN-STAGE.ply (view streams, as the "
            "pipe carries them)")(
            "noise-model", cli::po::value<std::string>()->default_value("auto")->value_name("NAME"),
            "sensor noise model of the distance and density cleaning: auto (the rig's sensors' "
            "model when they share one the denoisers know, else kinect_v2), kinect_v2, "
            "kinect_v1, sr300 or generic")(
            "crop-radius-m", cli::po::value<double>()->default_value(0.6)->value_name("M"),
            "object extraction radius around the sensors' common centre (0 = no crop)")(
            "method", cli::po::value<std::string>()->default_value("front")->value_name("NAME"),
            "surface reconstruction method of rgbd-mesh (front, poisson or advancing-front)")(
            "open",
            "keep the holes no sensor saw open (default: closed, as rgbd-mesh "
            "--watertight)")(
            "upsample", cli::po::value<int>()->default_value(8)->value_name("4|8"),
            "super-resolution: new points per depth point, 4 or 8 colour-pixel neighbours (0 = "
            "--skip upsample)");
    };
    return cli::run_tool(argc, argv, spec, [&](cli::Context& ctx) {
        if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one capture folder");
        if (ctx.output_path().empty()) throw cli::UsageError("give the mesh file with -o MESH");
        const std::string root = ctx.inputs().front();
        const fs::path mesh_path = ctx.output_path();
        const fs::path report_dir =
            ctx.options().count("report")
                ? fs::path(ctx.get<std::string>("report"))
                : fs::path(fs::path(mesh_path).replace_extension().string() + "_report");
        std::set<std::string> skip =
            parse_skip(ctx.options().count("skip") ? ctx.get<std::string>("skip") : "");
        reconstruction::ReconstructionOptions mesh_options;
        upsample::UpsampleOptions upsample_options;
        try {
            mesh_options.method = ctx.get<std::string>("method");
            mesh_options.watertight = ctx.options().count("open") == 0;
            mesh_options.check();
            const int neighbors = ctx.get<int>("upsample");
            if (neighbors != 0 && neighbors != 4 && neighbors != 8)
                throw cli::UsageError("--upsample must be 4 or 8 (0 = off), not " +
                                      std::to_string(neighbors));
            if (neighbors == 0)
                skip.insert("upsample");
            else
                upsample_options.neighbors = neighbors;
            upsample_options.check();
        } catch (const InputError& e) {
            throw cli::UsageError(e.what());
        }
        const std::string noise_name = ctx.get<std::string>("noise-model");
        std::optional<denoise::NoiseModel> noise_model;
        if (noise_name != "auto") {
            try {
                noise_model = denoise::parse_noise_model(noise_name);
            } catch (const InputError& e) {
                throw cli::UsageError(std::string("--noise-model: ") + e.what());
            }
        }
        frames::CloudOptions cloud_options;
        cli::ExtractionOptions extraction;
        extraction.crop_radius_m = ctx.get<double>("crop-radius-m");
        if (!(extraction.crop_radius_m >= 0)) throw cli::UsageError("--crop-radius-m must be >= 0");

        std::optional<fs::path> stages_dir;
        if (ctx.options().count("stages-dir")) {
            stages_dir = ctx.get<std::string>("stages-dir");
            std::error_code ec;
            fs::create_directories(*stages_dir, ec);
            if (ec)
                throw IoError(stages_dir->string() + ": cannot create the folder (" + ec.message() +
                              ")");
        }
        Report report;
        report["capture"] = root;
        report["mesh_file"] = mesh_path.string();
        report["skipped_stages"] = Report::array();
        for (const auto& s : kOptionalStages)
            if (skip.count(s)) report["skipped_stages"].push_back(s);
        Report& timings = report["timings_s"];
        StageLog stages;
        Stopwatch total;

        const io::Capture capture = io::open_capture(root);
        bool model_from_rig = false;
        const denoise::NoiseModel model =
            noise_model ? *noise_model : rig_noise_model(capture.rig, &model_from_rig);
        report["noise_model"] = denoise::to_string(model);
        denoise::DistanceOptions distance_options;
        distance_options.noise_model = model;
        denoise::DensityOptions density_options;
        density_options.noise_model = model;
        density_options.seed = ctx.seed();

        // 1. clouds, 2. distance-based cleaning and 3. super-resolution, one view at a time.
        Stopwatch watch;
        const auto jobs = cli::select_frames(
            capture, ctx.get<long long>("frameset"),
            ctx.options().count("frames") ? ctx.get<std::string>("frames") : std::string(), {},
            &ctx);
        double clean_time = 0, upsample_time = 0;
        std::size_t cloud_points = 0, clean_points = 0, upsample_views = 0;
        std::vector<PointCloud> views;
        report["views"] = Report::array();
        {
            auto bar = ctx.progress("clouds");
            const auto centre = cli::object_centre(capture, jobs);
            for (const auto& [id, position] : jobs) {
                Report v;
                const RgbdFrame frame = io::load_frame(capture, id, position);
                PointCloud cloud = cli::view_from_frame(frame, static_cast<int>(views.size()),
                                                        cloud_options, centre, extraction, v);
                cloud_points += cloud.size();
                if (!skip.count("distance")) {
                    Stopwatch clean_watch;
                    v["distance"] = denoise::remove_distance_outliers(cloud, distance_options);
                    clean_time += clean_watch.seconds();
                }
                clean_points += cloud.size();
                v["points_after_cleaning"] = cloud.size();
                if (cloud.size() < 100)
                    throw InputError(root + ": view " + std::to_string(cloud.view.id) + " (" + id +
                                     ") has only " + std::to_string(cloud.size()) +
                                     " points in the depth window");
                // Super-resolution where the colour camera has more pixels than the depth one.
                const bool finer_colour =
                    !frame.color.empty() && static_cast<double>(frame.color.total()) >
                                                static_cast<double>(frame.depth.total());
                if (!skip.count("upsample") && finer_colour && cloud.view.has_grid()) {
                    Stopwatch upsample_watch;
                    v["upsample"] = upsample::upsample_view(cloud, frame, upsample_options);
                    upsample_time += upsample_watch.seconds();
                    ++upsample_views;
                }
                report["views"].push_back(v);
                views.push_back(std::move(cloud));
                bar.update(static_cast<double>(views.size()) / jobs.size());
            }
        }
        const std::size_t upsampled_points = count_points(views);
        timings["clouds"] = watch.seconds() - clean_time - upsample_time;
        stages.add("clouds", timings["clouds"].get<double>(), 0, cloud_points,
                   {{"views", views.size()}});
        if (!skip.count("distance")) {
            timings["clean_distance"] = clean_time;
            stages.add("distance", clean_time, cloud_points, clean_points);
        }
        if (!skip.count("upsample")) {
            timings["upsample"] = upsample_time;
            stages.add("upsample", upsample_time, clean_points, upsampled_points,
                       {{"views", upsample_views}});
            if (upsample_views == 0)
                ctx.info("upsample: no view has a colour camera finer than its depth camera");
        }
        ctx.info("clouds: " + std::to_string(views.size()) + " views");
        save_stage(stages_dir, 1, "views", views);

        // 4. alignment.
        watch = Stopwatch();
        registration::MultiViewOptions align_options;
        {
            auto bar = ctx.progress("align");
            report["align"] = cli::align_stage(views, align_options, bar.callback());
        }
        timings["align"] = watch.seconds();
        save_stage(stages_dir, 2, "align", views);
        stages.add("align", timings["align"].get<double>(), upsampled_points, count_points(views));
        for (const auto& v : report["align"]["views"])
            if (v["verdict"] != "PASS")
                ctx.warn("view " + std::to_string(v["view"].get<int>()) + " (" +
                         v["sensor"].get<std::string>() + "): registration " +
                         v["verdict"].get<std::string>());

        // 5. density-based cleaning over the aligned views.
        if (!skip.count("density")) {
            watch = Stopwatch();
            const std::size_t in = count_points(views);
            {
                auto bar = ctx.progress("density");
                report["density"] =
                    denoise::remove_density_outliers(views, density_options, bar.callback());
            }
            timings["clean_density"] = watch.seconds();
            stages.add("density", timings["clean_density"].get<double>(), in, count_points(views));
            save_stage(stages_dir, 3, "density", views);
        }

        // Keep the aligned poses for the pose evaluation before the views are consumed.
        std::vector<PointCloud> pose_views;
        for (const auto& v : views) {
            PointCloud p;
            p.view = v.view;
            pose_views.push_back(std::move(p));
        }

        // 6. hole filling: one more view with the added points.
        if (!skip.count("fill")) {
            watch = Stopwatch();
            const std::size_t in = count_points(views);
            std::vector<PointCloud*> pointers;
            for (auto& v : views) pointers.push_back(&v);
            Report fill_report;
            std::optional<PointCloud> added;
            {
                auto bar = ctx.progress("fill");
                added =
                    cli::fill_stage(pointers, cli::FillStageOptions{}, fill_report, bar.callback());
            }
            if (fill_report.contains("note")) ctx.warn(fill_report["note"].get<std::string>());
            const std::size_t count = added ? added->size() : 0;
            if (added) views.push_back(std::move(*added));
            report["fill"] = fill_report;
            timings["fill"] = watch.seconds();
            stages.add("fill", timings["fill"].get<double>(), in, in + count,
                       {{"points_added", count}});
            save_stage(stages_dir, 4, "fill", views);
        }

        // The aligned points for the report's pictures.
        const render::Geometry input_geometry = render::from_views(views);

        // 7. merge + mesh.
        watch = Stopwatch();
        const std::size_t mesh_in = count_points(views);
        Mesh mesh;
        {
            auto bar = ctx.progress("mesh");
            Report mesh_report;
            mesh = cli::mesh_stage(std::move(views), mesh_options, mesh_report, bar.callback());
            report["mesh"] = mesh_report;
        }
        timings["mesh"] = watch.seconds();
        stages.add("mesh", timings["mesh"].get<double>(), mesh_in, mesh.number_of_vertices(),
                   {{"faces", mesh.number_of_faces()}});
        report["stages"] = stages.rows;
        // Slivers, folds, spikes, surface far from every input point, grey fill colours.
        report["mesh_quality"] = evaluation::mesh_quality(mesh, &input_geometry.vertices);
        report["counts"] = {{"views", pose_views.size()},
                            {"mesh_vertices", mesh.number_of_vertices()},
                            {"mesh_faces", mesh.number_of_faces()}};
        ViewInfo info;
        info.frame = ViewFrame::kWorld;
        info.sensor = "mesh";
        ctx.add_history(info);
        io::write_mesh(mesh_path, mesh, &info);

        // 8. evaluation against ground truth when there is some.
        std::string reference = ctx.options().count("reference")
                                    ? ctx.get<std::string>("reference")
                                    : (fs::path(root) / "gt" / "mesh.ply").string();
        std::optional<Mesh> reference_mesh;
        if (fs::exists(reference) || ctx.options().count("reference")) {
            watch = Stopwatch();
            evaluation::MetricOptions metric_options;
            metric_options.taus_m = {0.001, 0.002, 0.005};
            metric_options.seed = ctx.seed();
            cli::LoadedResult result;
            result.mesh = mesh;
            reference_mesh = io::read_mesh(reference);
            report["evaluation"]["reference"] = reference;
            report["evaluation"]["surface"] =
                cli::evaluate_surface(result, *reference_mesh, metric_options);
            const fs::path gt_poses = fs::path(root) / "gt" / "world_from_depth.json";
            if (fs::exists(gt_poses))
                report["evaluation"]["poses"] =
                    cli::evaluate_poses(pose_views, gt_poses.string(), /*remove_gauge=*/true);
            timings["evaluation"] = watch.seconds();
        }

        // 9. the report page with pictures.
        watch = Stopwatch();
        cli::ReportPage page;
        {
            auto bar = ctx.progress("pictures");
            cli::PictureInputs pictures;
            pictures.input = &input_geometry;
            pictures.result = &mesh;
            pictures.reference = reference_mesh ? &*reference_mesh : nullptr;
            Report picture_info;
            std::vector<cli::ReportImage> images;
            cli::render_report_pictures(pictures, images, picture_info);
            report["report"] = picture_info;
            timings["pictures"] = watch.seconds();
            timings["total"] = total.seconds();
            page = report_page(report);
            page.images = std::move(images);
        }
        page.metrics = report;
        cli::write_report(report_dir, page);
        ctx.metrics()["reconstruct"] = report;
        ctx.note("mesh: " + mesh_path.string() + " (" +
                 std::to_string(report["counts"]["mesh_faces"].get<std::size_t>()) + " faces)");
        ctx.note("report: " + (report_dir / "index.html").string());
        if (report.contains("evaluation")) {
            const auto& s = report["evaluation"]["surface"];
            std::ostringstream line;
            line.precision(4);
            line << "against " << reference << ": F-score@2mm " << s.value("fscore_2mm", 0.0)
                 << ", F-score@5mm " << s.value("fscore_5mm", 0.0) << ", invented "
                 << s.value("invented_surface_fraction", 0.0) * 100 << "%, completeness "
                 << s.value("completeness_mean_m", 0.0) * 1000 << " mm";
            ctx.note(line.str());
        }
    });
}
