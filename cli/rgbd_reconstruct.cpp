// rgbd-reconstruct: the whole pipeline on a capture folder with defaults, a mesh and a report.
#include <filesystem>
#include <fstream>
#include <sstream>

#include "algorithms/denoise/statistical_outliers.hpp"
#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/render/picture.hpp"
#include "algorithms/upsample/upsample_view.hpp"
#include "cli/common/report_page.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

/// The report page: pictures (input, mesh, heat map), evaluation, stages, views.
cli::ReportPage report_page(const Report& report) {
    cli::ReportPage page;
    page.title = "rgbd-reconstruct";
    page.facts = {{"capture", report["capture"].get<std::string>()},
                  {"mesh", report["mesh_file"].get<std::string>()}};
    if (report.contains("evaluation"))
        page.tables.push_back(
            cli::side_by_side("Against the ground truth", {{"result", report["evaluation"]}}));
    cli::ReportTable stages = cli::side_by_side(
        "Stages", {{"", Report{{"time_s", report["timings_s"]}, {"counts", report["counts"]}}}});
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
    spec.usage = "rgbd-reconstruct CAPTURE_DIR -o MESH [--report DIR] [options]";
    spec.description =
        "Runs the whole pipeline on a capture folder with the defaults of each stage: coloured "
        "clouds per view (rgbd-cloud), statistical outlier removal (rgbd-clean --statistical), "
        "multi-view ICP from the rig's poses (rgbd-align), merge and surface reconstruction "
        "(rgbd-mesh --watertight: a closed coloured mesh; --open keeps unseen holes). Writes the "
        "mesh and a report folder (metrics.json and index.html) with "
        "per-stage counts and timings, per-view registration verdicts and, when the capture has "
        "ground truth (gt/ of rgbd-synth) or --reference is given, the metrics of rgbd-eval.";
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
            "crop-radius-m", cli::po::value<double>()->default_value(0.6)->value_name("M"),
            "object extraction radius around the sensors' common centre (0 = no crop)")(
            "method", cli::po::value<std::string>()->default_value("front")->value_name("NAME"),
            "surface reconstruction method of rgbd-mesh (front, poisson or advancing-front)")(
            "open",
            "keep the holes no sensor saw open (default: closed, as rgbd-mesh "
            "--watertight)")(
            "upsample", cli::po::value<int>()->default_value(0)->value_name("0|4|8"),
            "colour-guided super-resolution per view before alignment (rgbd-upsample): 0 = off, "
            "4 or 8 neighbours");
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
        reconstruction::ReconstructionOptions mesh_options;
        try {
            mesh_options.method = ctx.get<std::string>("method");
            mesh_options.watertight = ctx.options().count("open") == 0;
            mesh_options.check();
        } catch (const InputError& e) {
            throw cli::UsageError(e.what());
        }
        Report report;
        report["capture"] = root;
        report["mesh_file"] = mesh_path.string();
        Report& timings = report["timings_s"];
        Stopwatch total;

        // 1. clouds + 2. statistical cleaning, one view at a time.
        Stopwatch watch;
        const io::Capture capture = io::open_capture(root);
        const auto jobs = cli::select_frames(
            capture, ctx.get<long long>("frameset"),
            ctx.options().count("frames") ? ctx.get<std::string>("frames") : std::string(), {},
            &ctx);
        frames::CloudOptions cloud_options;
        cli::ExtractionOptions extraction;
        extraction.crop_radius_m = ctx.get<double>("crop-radius-m");
        if (!(extraction.crop_radius_m >= 0)) throw cli::UsageError("--crop-radius-m must be >= 0");
        denoise::StatisticalOptions clean_options;
        const int upsample_neighbors = ctx.get<int>("upsample");
        upsample::UpsampleOptions upsample_options;
        upsample_options.neighbors = upsample_neighbors;
        if (upsample_neighbors != 0 && upsample_neighbors != 4 && upsample_neighbors != 8)
            throw cli::UsageError("--upsample must be 0, 4 or 8");
        double upsample_time = 0;
        std::vector<PointCloud> views;
        report["views"] = Report::array();
        double clean_time = 0;
        {
            auto bar = ctx.progress("clouds");
            const auto centre = cli::object_centre(capture, jobs);
            for (const auto& [id, position] : jobs) {
                Report v;
                PointCloud cloud =
                    cli::load_view(capture, id, position, static_cast<int>(views.size()),
                                   cloud_options, centre, extraction, v);
                Stopwatch clean_watch;
                Report clean = denoise::remove_statistical_outliers(cloud, clean_options);
                clean_time += clean_watch.seconds();
                v["points_after_cleaning"] = cloud.size();
                if (upsample_neighbors > 0) {
                    Stopwatch upsample_watch;
                    v["upsample"] = upsample::upsample_view(
                        cloud, io::load_frame(capture, id, position), upsample_options);
                    upsample_time += upsample_watch.seconds();
                }
                report["views"].push_back(v);
                if (cloud.size() < 100)
                    throw InputError(root + ": view " + std::to_string(cloud.view.id) + " (" + id +
                                     ") has only " + std::to_string(cloud.size()) +
                                     " points in the depth window");
                views.push_back(std::move(cloud));
                bar.update(static_cast<double>(views.size()) / jobs.size());
            }
        }
        timings["clouds"] = watch.seconds() - clean_time - upsample_time;
        timings["clean"] = clean_time;
        timings["upsample"] = upsample_time;
        ctx.info("clouds: " + std::to_string(views.size()) + " views");

        // 3. alignment.
        watch = Stopwatch();
        registration::MultiViewOptions align_options;
        {
            auto bar = ctx.progress("align");
            report["align"] = cli::align_stage(views, align_options, bar.callback());
        }
        timings["align"] = watch.seconds();
        for (const auto& v : report["align"]["views"])
            if (v["verdict"] != "PASS")
                ctx.warn("view " + std::to_string(v["view"].get<int>()) + " (" +
                         v["sensor"].get<std::string>() + "): registration " +
                         v["verdict"].get<std::string>());

        // Keep the aligned poses for the pose evaluation before the views are consumed.
        std::vector<PointCloud> pose_views;
        for (const auto& v : views) {
            PointCloud p;
            p.view = v.view;
            pose_views.push_back(std::move(p));
        }

        // The aligned points for the report's pictures.
        const render::Geometry input_geometry = render::from_views(views);

        // 4. merge + mesh.
        watch = Stopwatch();
        Mesh mesh;
        {
            auto bar = ctx.progress("mesh");
            Report mesh_report;
            mesh = cli::mesh_stage(std::move(views), mesh_options, mesh_report, bar.callback());
            report["mesh"] = mesh_report;
        }
        timings["mesh"] = watch.seconds();
        report["counts"] = {{"views", pose_views.size()},
                            {"mesh_vertices", mesh.number_of_vertices()},
                            {"mesh_faces", mesh.number_of_faces()}};
        ViewInfo info;
        info.frame = ViewFrame::kWorld;
        info.sensor = "mesh";
        ctx.add_history(info);
        io::write_mesh(mesh_path, mesh, &info);

        // 5. evaluation against ground truth when there is some.
        std::string reference = ctx.options().count("reference")
                                    ? ctx.get<std::string>("reference")
                                    : (fs::path(root) / "gt" / "mesh.ply").string();
        std::optional<Mesh> reference_mesh;
        if (fs::exists(reference) || ctx.options().count("reference")) {
            watch = Stopwatch();
            evaluation::MetricOptions metric_options;
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

        // 6. the report page with pictures.
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
            line << "against " << reference << ": F-score@5mm " << s.value("fscore_5mm", 0.0)
                 << ", F-score@2mm " << s.value("fscore_2mm", 0.0) << ", Chamfer "
                 << s.value("chamfer_m", 0.0) * 1000 << " mm";
            ctx.note(line.str());
        }
    });
}
