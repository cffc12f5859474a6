// rgbd-reconstruct: the whole pipeline on a capture folder with defaults, a mesh and a report.
#include <filesystem>
#include <fstream>
#include <sstream>

#include "algorithms/denoise/statistical_outliers.hpp"
#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/upsample/upsample_view.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

std::string html_escape(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '<')
            out += "&lt;";
        else if (c == '>')
            out += "&gt;";
        else if (c == '&')
            out += "&amp;";
        else
            out += c;
    }
    return out;
}

std::string format_value(const Report& v) {
    if (v.is_number_float()) {
        std::ostringstream s;
        s.precision(4);
        s << v.get<double>();
        return s.str();
    }
    return v.is_string() ? v.get<std::string>() : v.dump();
}

void table_rows(std::ostringstream& html, const Report& r, const std::string& prefix) {
    for (auto it = r.begin(); it != r.end(); ++it) {
        const std::string key = prefix.empty() ? it.key() : prefix + "." + it.key();
        if (it->is_object())
            table_rows(html, *it, key);
        else if (!it->is_array())
            html << "<tr><td>" << html_escape(key) << "</td><td>" << html_escape(format_value(*it))
                 << "</td></tr>\n";
    }
}

std::string report_html(const Report& report) {
    std::ostringstream html;
    html << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>rgbd-reconstruct report"
            "</title><style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
            "td{border:1px solid #ccc;padding:2px 8px}td:last-child{text-align:right}"
            "</style></head><body>\n<h1>rgbd-reconstruct</h1>\n";
    html << "<p>capture: " << html_escape(report["capture"].get<std::string>())
         << "<br>mesh: " << html_escape(report["mesh_file"].get<std::string>()) << "</p>\n";
    if (report.contains("evaluation")) {
        html << "<h2>Against the ground truth</h2>\n<table>\n";
        table_rows(html, report["evaluation"], "");
        html << "</table>\n";
    }
    html << "<h2>Stages</h2>\n<table>\n";
    table_rows(html, report["timings_s"], "time_s");
    table_rows(html, report["counts"], "");
    html << "</table>\n<h2>Views</h2>\n<table>\n<tr><td>view</td><td>sensor</td><td>points</td>"
            "<td>after cleaning</td><td>verdict</td><td>fitness</td><td>rmse (mm)</td></tr>\n";
    for (const auto& v : report["align"]["views"]) {
        const int id = v["view"].get<int>();
        html << "<tr><td>" << id << "</td><td>" << html_escape(v["sensor"].get<std::string>())
             << "</td><td>" << report["views"][id]["points"] << "</td><td>"
             << report["views"][id]["points_after_cleaning"] << "</td><td>"
             << v["verdict"].get<std::string>() << "</td><td>" << format_value(v["fitness"])
             << "</td><td>" << format_value(Report(v["inlier_rmse_m"].get<double>() * 1000))
             << "</td></tr>\n";
    }
    html << "</table>\n<p>Full numbers: <a href=\"metrics.json\">metrics.json</a></p>\n"
            "</body></html>\n";
    return html.str();
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
        "(rgbd-mesh). Writes the mesh and a report folder (metrics.json and index.html) with "
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
            "method", cli::po::value<std::string>()->default_value("poisson")->value_name("NAME"),
            "surface reconstruction method (poisson or advancing-front)")(
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
        if (fs::exists(reference) || ctx.options().count("reference")) {
            watch = Stopwatch();
            evaluation::MetricOptions metric_options;
            metric_options.seed = ctx.seed();
            cli::LoadedResult result;
            result.mesh = std::move(mesh);
            report["evaluation"]["reference"] = reference;
            report["evaluation"]["surface"] =
                cli::evaluate_surface(result, io::read_mesh(reference), metric_options);
            const fs::path gt_poses = fs::path(root) / "gt" / "world_from_depth.json";
            if (fs::exists(gt_poses))
                report["evaluation"]["poses"] =
                    cli::evaluate_poses(pose_views, gt_poses.string(), /*remove_gauge=*/true);
            timings["evaluation"] = watch.seconds();
        }
        timings["total"] = total.seconds();

        fs::create_directories(report_dir);
        io::write_text_atomic(report_dir / "metrics.json", report.dump(2) + "\n");
        io::write_text_atomic(report_dir / "index.html", report_html(report));
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
