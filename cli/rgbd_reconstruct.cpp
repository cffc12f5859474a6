// rgbd-reconstruct: the whole method on a capture folder with defaults, a mesh and a report.
// The chain is pipeline::reconstruct (the README's pipe, stage for stage, with the same
// defaults; a test checks that both give the same mesh); this file maps the arguments, writes
// the files and shows progress:
//   rgbd-cloud | rgbd-clean --distance | rgbd-upsample | rgbd-align | rgbd-clean --density
//     | rgbd-fill | rgbd-mesh --watertight
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "algorithms/render/picture.hpp"
#include "algorithms/texture/texture_mesh.hpp"
#include "cli/common/report_page.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "io/textured_mesh_io.hpp"
#include "pipeline/reconstruct.hpp"
#include "pipeline/texture_views.hpp"
#include "toolkit/error.hpp"
#include "toolkit/wait_at_exit.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

/// Parses --skip "a,b": the stage names, each one of kOptionalStages.
std::set<std::string> parse_skip(const std::string& text) {
    std::set<std::string> skip;
    std::stringstream in(text);
    std::string name;
    std::string valid;
    for (const auto& s : pipeline::optional_stages()) valid += (valid.empty() ? "" : ", ") + s;
    while (std::getline(in, name, ',')) {
        if (name.empty()) continue;
        if (std::find(pipeline::optional_stages().begin(), pipeline::optional_stages().end(),
                      name) == pipeline::optional_stages().end())
            throw cli::UsageError("--skip: unknown stage '" + name + "' (valid: " + valid + ")");
        skip.insert(name);
    }
    return skip;
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
    if (report.contains("texture"))  // the pictures show it; the viewer turns it
        page.facts.push_back(
            {"textured model", "rgbd-view " + report["mesh_file"].get<std::string>()});
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

void run_reconstruct(cli::Context& ctx) {
    if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one capture folder");
    if (ctx.output_path().empty()) throw cli::UsageError("give the mesh file with -o MESH");
    if (ctx.options().count("refine-colour") && !io::is_textured_format(ctx.output_path()))
        throw cli::UsageError("--refine-colour applies only to a textured model (-o .obj or .glb)");
    const std::string root = ctx.inputs().front();
    const fs::path mesh_path = ctx.output_path();
    const fs::path report_dir =
        ctx.options().count("report")
            ? fs::path(ctx.get<std::string>("report"))
            : fs::path(fs::path(mesh_path).replace_extension().string() + "_report");
    pipeline::ReconstructOptions options;
    options.skip = parse_skip(ctx.options().count("skip") ? ctx.get<std::string>("skip") : "");
    try {
        options.mesh.method = ctx.get<std::string>("method");
        options.mesh.watertight = ctx.options().count("open") == 0;
        if (ctx.options().count("no-carve-closure")) options.mesh.carve_steps = 0;
        options.mesh.repair_self_intersections =
            ctx.options().count("repair-self-intersections") > 0;
        options.mesh.check();
        const int neighbors = ctx.get<int>("upsample");
        if (neighbors != 0 && neighbors != 4 && neighbors != 8)
            throw cli::UsageError("--upsample must be 4 or 8 (0 = off), not " +
                                  std::to_string(neighbors));
        if (neighbors == 0)
            options.skip.insert("upsample");
        else
            options.upsample.neighbors = neighbors;
        options.upsample.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    const std::string noise_name = ctx.get<std::string>("noise-model");
    if (noise_name != "auto") {
        try {
            options.noise_model = denoise::parse_noise_model(noise_name);
        } catch (const InputError& e) {
            throw cli::UsageError(std::string("--noise-model: ") + e.what());
        }
    }
    try {
        options.stand = pipeline::parse_stand_mode(ctx.get<std::string>("stand"));
    } catch (const InputError& e) {
        throw cli::UsageError(std::string("--stand: ") + e.what());
    }
    options.extraction.crop_radius_m = ctx.get<double>("crop-radius-m");
    options.extraction.enabled = !ctx.options().count("no-extract");
    options.extraction.subject.remove_ground = !ctx.options().count("keep-ground");
    if (!(options.extraction.crop_radius_m >= 0))
        throw cli::UsageError("--crop-radius-m must be >= 0");
    options.seed = ctx.seed();

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
    for (const auto& s : pipeline::optional_stages())
        if (options.skip.count(s)) report["skipped_stages"].push_back(s);
    Stopwatch total;

    const io::Capture capture = io::open_capture(root);
    const auto jobs = cli::select_frames(
        capture, ctx.get<long long>("frameset"),
        ctx.options().count("frames") ? ctx.get<std::string>("frames") : std::string(), {}, &ctx);
    // Progress bars, messages and --stages-dir for the library's chain.
    pipeline::ReconstructHooks hooks;
    std::unique_ptr<cli::ProgressBar> bar;
    hooks.stage_begin = [&](const std::string& stage) {
        bar.reset(new cli::ProgressBar(ctx.progress(stage)));
        return bar->callback();
    };
    hooks.stage_end = [&](const std::string&) { bar.reset(); };
    hooks.warn = [&](const std::string& message) { ctx.warn(message); };
    hooks.info = [&](const std::string& message) { ctx.info(message); };
    hooks.views_after = [&](int index, const std::string& stage,
                            const std::vector<PointCloud>& views) {
        save_stage(stages_dir, index, stage, views);
    };
    // 9. (early) the report's view (fitted to the input points), its input picture and the
    // extraction picture need the input points only: rendered beside the mesh stage's
    // sequential steps.
    std::optional<cli::ReportImage> extraction, input_image;
    std::optional<cli::PictureView> view;
    hooks.beside_mesh = [&](const pipeline::ReconstructResult& r) {
        if (r.input.vertices.empty()) return;
        view = cli::picture_view(r.input, r.input.sensors);
        input_image = cli::input_picture(r.input, view->camera);
        if (!r.removed.empty()) extraction = cli::extraction_picture(r.input, r.removed);
    };
    pipeline::ReconstructResult result = pipeline::reconstruct(capture, jobs, options, hooks);
    const Mesh& mesh = result.mesh;
    report.update(result.report);
    // 7b. -o model.obj|glb: the texture from the colour images, posed by the aligned views.
    std::optional<TexturedMesh> textured;
    if (io::is_textured_format(mesh_path)) {
        Stopwatch watch;
        Report texture_report;
        {
            auto texture_bar = ctx.progress("texture");
            const auto colour_views = pipeline::load_texture_views(capture, jobs, &result.poses);
            texture::TextureOptions texture_options;
            texture_options.refine.enabled = ctx.options().count("refine-colour") > 0;
            texture_options.refine.iterations = ctx.get<int>("refine-colour-iterations");
            textured = texture::texture_mesh(mesh, colour_views, texture_options, texture_report,
                                             texture_bar.callback());
        }
        cli::warn_refused_colour_poses(ctx, texture_report);
        report["texture"] = texture_report;
        result.stages.push_back({"texture",
                                 watch.seconds(),
                                 mesh.number_of_faces(),
                                 textured->faces.size(),
                                 {{"unseen_faces", texture_report["selection"]["unseen_faces"]},
                                  {"charts", texture_report["atlas"]["charts"]}}});
    }
    report["stages"] = result.stages_report();
    Report& timings = report["timings_s"];
    timings = result.timings();
    ViewInfo info;
    info.frame = ViewFrame::kWorld;
    info.sensor = "mesh";
    ctx.add_history(info);
    if (textured)
        io::write_textured_mesh(mesh_path, *textured,
                                std::string("rgbd-reconstruct ") + cli::kVersion);
    else
        io::write_mesh(mesh_path, mesh, &info);

    // 8. evaluation against ground truth when there is some, in a task beside 9. the report
    // pictures (the evaluation's distance structures are built on one thread; the pictures are
    // parallel loops, isolated so that this thread does not pick the evaluation up mid-way).
    std::string reference = ctx.options().count("reference")
                                ? ctx.get<std::string>("reference")
                                : (fs::path(root) / "gt" / "mesh.ply").string();
    std::optional<Mesh> reference_mesh;
    Report evaluation;
    double evaluation_time = 0.0;
    tbb::task_group evaluation_task;
    const WaitAtExit wait_at_exit{&evaluation_task};  // the task reads this scope's locals
    if (fs::exists(reference) || ctx.options().count("reference")) {
        reference_mesh = io::read_mesh(reference);
        evaluation::MetricOptions metric_options;
        metric_options.taus_m = {0.001, 0.002, 0.005};
        metric_options.seed = ctx.seed();
        evaluation_task.run([&, metric_options] {
            Stopwatch watch;
            cli::LoadedResult loaded;
            loaded.mesh = mesh;
            evaluation["reference"] = reference;
            evaluation["surface"] = cli::evaluate_surface(loaded, *reference_mesh, metric_options);
            const fs::path gt_poses = fs::path(root) / "gt" / "world_from_depth.json";
            if (fs::exists(gt_poses))
                evaluation["poses"] =
                    cli::evaluate_poses(result.poses, gt_poses.string(), /*remove_gauge=*/true);
            evaluation_time = watch.seconds();
        });
    }

    Stopwatch watch;
    cli::ReportPage page;
    std::vector<cli::ReportImage> images;
    {
        auto picture_bar = ctx.progress("pictures");
        cli::PictureInputs pictures;
        pictures.input = &result.input;
        pictures.result = &mesh;
        pictures.textured = textured ? &*textured : nullptr;
        pictures.reference = reference_mesh ? &*reference_mesh : nullptr;
        if (view && input_image) {
            pictures.view = &*view;
            pictures.input_image = &*input_image;
        }
        Report picture_info;
        tbb::this_task_arena::isolate([&] {
            cli::render_report_pictures(pictures, images, picture_info);
            if (!extraction && !result.removed.empty())
                extraction = cli::extraction_picture(result.input, result.removed);
            if (extraction && !extraction->file.empty()) images.push_back(std::move(*extraction));
        });
        report["report"] = picture_info;
        timings["pictures"] = watch.seconds();
    }
    evaluation_task.wait();
    if (reference_mesh) {
        report["evaluation"] = std::move(evaluation);
        timings["evaluation"] = evaluation_time;
    }
    timings["total"] = total.seconds();
    page = report_page(report);
    page.images = std::move(images);
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
}

const cli::ToolSpec kSpec{
    .name = "rgbd-reconstruct",
    .usage = "rgbd-reconstruct CAPTURE_DIR -o MESH [--report DIR] [--skip STAGE[,STAGE]] [options]",
    .description =
        "Runs the whole method on a capture folder with the defaults of each stage, in the "
        "order of the README's pipe: coloured clouds per view (rgbd-cloud), adaptive "
        "distance-based noise removal per view (rgbd-clean --distance), colour-guided "
        "super-resolution (rgbd-upsample, 8 neighbours; only for sensors whose colour camera "
        "has more pixels than the depth camera), multi-view registration from the rig's poses "
        "(rgbd-align), adaptive density-based noise removal over the aligned views (rgbd-clean "
        "--density; before it, on turntable captures, the stand the object stands on is "
        "removed: --stand), hole filling (rgbd-fill: small holes, head top, large holes, only "
        "where no sensor saw the surface) and surface reconstruction (rgbd-mesh --watertight: "
        "a closed coloured mesh; --open keeps unseen holes). The same options through the pipe "
        "give the same mesh. --skip leaves stages out (distance, upsample, density, fill) for "
        "comparisons. Writes the mesh and a report folder (metrics.json and index.html) with "
        "each stage's time and point counts in and out, per-view registration verdicts, the "
        "mesh's quality and, when the capture has ground truth (gt/ of rgbd-synth) or "
        "--reference is given, the metrics of rgbd-eval. -o MODEL.obj or MODEL.glb adds the "
        "texturing of rgbd-texture as the last stage (colour images of the same frames, posed by "
        "the aligned views): OBJ + MTL + PNG or a glTF binary; .ply keeps vertex colours.",
    .example = "rgbd-reconstruct cap/ -o bust.ply --report report/",
    .writes_stream = false,
    .reads_stream = false,
    .writes_file = true,
    .ranges = {{"crop-radius-m", Range::closed(0, 100), "m"},
               {"refine-colour-iterations", Range::closed(1, 1000)}},
    .scopes = {{{"open"}, {"no-carve-closure"}, /*not_with=*/true},
               {{"refine-colour"}, {"refine-colour-iterations"}}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("report", cli::value<std::string>("DIR"),
                        "report folder (default: MESH without extension + _report)")(
            "frameset", cli::value<long long>(0, "N"),
            "frame set to reconstruct (multi-sensor captures)")(
            "frames", cli::value<std::string>("A:B[:STEP]"),
            "frame positions (single-sensor sequences; default all)")(
            "reference", cli::value<std::string>("MESH"),
            "reference surface for the evaluation (default: CAPTURE/gt/mesh.ply if present)")(
            "skip", cli::value<std::string>("STAGE[,STAGE]"),
            "leave stages out of the chain: distance, upsample, density, fill")(
            "stages-dir", cli::value<std::string>("DIR"),
            "also write the views after each stage to DIR/NN-STAGE.ply (view streams, as the "
            "pipe carries them)")(
            "noise-model", cli::value<std::string>("auto", "NAME"),
            "sensor noise model of the distance and density cleaning: auto (the rig's sensors' "
            "model when they share one the denoisers know, else kinect_v2), kinect_v2, "
            "kinect_v1, sr300 or generic")(
            "crop-radius-m",
            cli::value(pipeline::ReconstructOptions{}.extraction.crop_radius_m, "M"),
            "override of the object extraction's extent: keep a ball of this radius around "
            "where the sensors' axes converge (0 = the subject's extent from the data: the "
            "connected regions above the ground that the sensors look at together)")(
            "keep-ground", "object extraction: keep the ground (floor, platter) in the views")(
            "no-extract", "no object extraction: every point in the depth window is kept")(
            "method", cli::value(pipeline::ReconstructOptions{}.mesh.method, "NAME"),
            "surface reconstruction method of rgbd-mesh (front, poisson or advancing-front)")(
            "stand", cli::value<std::string>("auto", "MODE"),
            "the stand (turntable platter) below the object, after the alignment: auto (remove "
            "it on single-sensor captures of several views: turntable), remove or keep")(
            "open",
            "keep the holes no sensor saw open (default: closed, as rgbd-mesh --watertight)")(
            "no-carve-closure",
            "keep the closed holes' faired patches as they are (default: carved back out of the "
            "space at least two sensors saw empty, as rgbd-mesh)")(
            "repair-self-intersections",
            "remove the mesh's faces that cross others and refill their holes, last (as "
            "rgbd-mesh)")(
            "refine-colour",
            "-o .obj/.glb: refine the colour cameras' poses against the mesh by photometric "
            "consistency before texturing (as rgbd-texture --refine-colour)")(
            "refine-colour-iterations", cli::value(texture::RefineOptions{}.iterations, "N"),
            "most Gauss-Newton iterations per pyramid level of --refine-colour")(
            "upsample", cli::value(pipeline::ReconstructOptions{}.upsample.neighbors, "4|8"),
            "super-resolution: new points per depth point, 4 or 8 colour-pixel neighbours (0 = "
            "--skip upsample)");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_reconstruct); }
