// rgbd-eval: metrics of a reconstructed mesh or cloud (and of estimated poses) against ground
// truth; how well a mesh explains a capture's own observations (--observed, real captures
// without truth); side by side with Open3D's Screened Poisson on the same input, or with
// Open3D's TSDF fusion and Screened Poisson on the same observations (--baseline); a report
// page with pictures (--report).
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>

#include "algorithms/evaluation/mesh_quality.hpp"
#include "algorithms/evaluation/metrics.hpp"
#include "algorithms/evaluation/observed.hpp"
#include "algorithms/render/picture.hpp"
#include "cli/common/report_page.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/temp_folder.hpp"
#include "cli/common/tool.hpp"
#include "cli/eval_colour.hpp"
#include "cli/eval_observed.hpp"
#include "io/mesh_io.hpp"
#include "pipeline/observed.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

constexpr const char* kPeerScript = "open3d_screened_poisson.py";
constexpr const char* kPython = "/usr/bin/python3";

/// Writes the input points for the peer: x y z, normals (given when every view has them),
/// the position of each point's sensor (NaN when unknown), colours (grey when absent).
bool write_peer_input(const fs::path& path, const std::vector<PointCloud>& views) {
    bool normals = !views.empty();
    std::size_t count = 0;
    for (const auto& v : views) {
        normals = normals && v.points.has_normal_map();
        count += v.size();
    }
    std::ofstream out(path, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\ncomment normals "
        << (normals ? "given" : "missing") << "\nelement vertex " << count << "\n";
    for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "sx", "sy", "sz"})
        out << "property float " << p << "\n";
    out << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (const auto& v : views) {
        // As render::from_views: a sensor-frame view without a pose is taken as it is.
        Pose world_from_view = Pose::Identity();
        if (v.view.frame == ViewFrame::kSensor && v.view.world_from_sensor)
            world_from_view = *v.view.world_from_sensor;
        Eigen::Vector3f sensor(nan, nan, nan);
        if (v.view.world_from_sensor)
            sensor = v.view.world_from_sensor->translation().cast<float>();
        else if (v.view.frame == ViewFrame::kSensor && v.view.intrinsics)
            sensor = Eigen::Vector3f::Zero();
        std::optional<PointCloud::ColorMaps> colors;
        if (v.has_colors()) colors = v.colors();
        for (auto i : v.points) {
            const Eigen::Vector3f p = (world_from_view * to_eigen(v.points.point(i))).cast<float>();
            Eigen::Vector3f n = Eigen::Vector3f::Zero();
            if (normals)
                n = (world_from_view.linear() * to_eigen(v.points.normal(i))).cast<float>();
            const float f[9] = {p.x(), p.y(),      p.z(),      n.x(),     n.y(),
                                n.z(), sensor.x(), sensor.y(), sensor.z()};
            out.write(reinterpret_cast<const char*>(f), sizeof f);
            const Rgb c = colors ? colors->get(i) : Rgb{160, 160, 160};
            const std::uint8_t rgb[3] = {c.r, c.g, c.b};
            out.write(reinterpret_cast<const char*>(rgb), 3);
        }
    }
    RGBD_CHECK_AS(IoError, out.good(), path.string() + ": cannot write");
    return normals;
}

/// Statistics of the per-vertex distance of a mesh to the input points (real data without a
/// reference: how far the surface strays from what was measured).
Report input_distance(const Mesh& mesh, const std::vector<Eigen::Vector3d>& input, double tau) {
    std::vector<Eigen::Vector3d> v;
    for (const auto i : mesh.vertices()) v.push_back(to_eigen(mesh.point(i)));
    if (v.empty()) return nullptr;
    std::vector<double> d = evaluation::distances_to_points(v, input);
    std::size_t far = 0;
    for (double x : d) far += x > tau;
    auto q = [&](double f) { return count_quantile(d, f); };
    char key[64];
    std::snprintf(key, sizeof key, "vertices_farther_than_%gmm", tau * 1000);
    return {{"median_mm", q(0.5) * 1000},
            {"p95_mm", q(0.95) * 1000},
            {key, double(far) / double(d.size())}};
}

struct BaselineRun {
    int depth = 0;
    Mesh mesh;
    Report report;
};

/// Runs the peer script at each depth and reads its meshes back.
std::vector<BaselineRun> run_screened_poisson(const std::vector<PointCloud>& input,
                                              const std::vector<int>& depths, double trim,
                                              Report& info, const cli::Context& ctx) {
    const fs::path script = cli::find_peer_script(kPeerScript);
    RGBD_CHECK_AS(IoError, fs::exists(kPython),
                  std::string("--baseline screened-poisson needs Debian's ") + kPython +
                      " with python3-open3d");
    const cli::TempFolder tmp("rgbd-eval-");
    const fs::path points = tmp.path / "input.ply";
    const bool normals = write_peer_input(points, input);
    bool colored = !input.empty();
    for (const auto& v : input) colored = colored && v.has_colors();
    info["normals"] = normals ? "given" : "estimated (Open3D, oriented towards the sensors)";
    std::string depth_list;
    for (int d : depths) depth_list += (depth_list.empty() ? "" : ",") + std::to_string(d);
    std::ostringstream trim_text;
    trim_text << trim;
    const std::string command = std::string(kPython) + " " + cli::shell_quote(script.string()) +
                                " --input " + cli::shell_quote(points.string()) + " --out-dir " +
                                cli::shell_quote(tmp.path.string()) + " --depths " + depth_list +
                                " --trim-quantile " + trim_text.str() +
                                (colored ? "" : " --no-colors");
    // Runs the script; its exit code (the shell's: 128 + N when signal N ended it).
    std::string output;
    const auto run_peer = [&](const std::string& cmd) {
        ctx.info("baseline: " + cmd);
        FILE* pipe = ::popen(cmd.c_str(), "r");
        RGBD_CHECK_AS(IoError, pipe != nullptr, "cannot run " + std::string(kPython));
        output.clear();
        char buf[4096];
        while (std::size_t n = std::fread(buf, 1, sizeof buf, pipe)) output.append(buf, n);
        const int status = ::pclose(pipe);
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    };
    int code = run_peer(command);
    if (code == 128 + SIGSEGV || code == 128 + SIGABRT) {
        // Open3D's multi-threaded Poisson solver crashes now and then (a race: Open3D issue
        // 6828, PoissonRecon issue 298); one thread does not.
        ctx.warn("Open3D Screened Poisson crashed (exit code " + std::to_string(code) +
                 ", a known race in its multi-threaded solver); running it again on one thread");
        info["threads"] = 1;
        code = run_peer(command + " --threads 1");
    }
    if (code == 3)
        throw InputError(
            "--baseline screened-poisson needs python3-open3d (apt-get install python3-open3d)");
    RGBD_CHECK_AS(AlgorithmError, code == 0,
                  "Open3D Screened Poisson failed (" + script.string() + " exit code " +
                      std::to_string(code) + ")");
    std::vector<BaselineRun> runs;
    std::istringstream lines(output);
    std::string line;
    while (std::getline(lines, line)) {
        if (line.empty()) continue;
        Report r = Report::parse(line, nullptr, false);
        RGBD_CHECK_AS(AlgorithmError, r.is_object() && r.contains("file"),
                      script.string() + ": unexpected output: " + line);
        BaselineRun run;
        run.depth = r["depth"].get<int>();
        run.mesh = io::read_mesh(r["file"].get<std::string>());
        r.erase("file");
        run.report = r;
        runs.push_back(std::move(run));
    }
    RGBD_CHECK_AS(AlgorithmError, runs.size() == depths.size(),
                  script.string() + ": expected " + std::to_string(depths.size()) +
                      " meshes, got " + std::to_string(runs.size()));
    return runs;
}

std::string cell(const Report& r, const std::string& key, double scale = 1.0) {
    if (!r.is_object() || !r.contains(key) || !r[key].is_number()) return "-";
    std::ostringstream s;
    s.precision(4);
    s << r[key].get<double>() * scale;
    return s.str();
}

std::string trim_text(double q) {
    std::ostringstream s;
    s << q;
    return s.str();
}

/// Parses "WxH".
std::pair<int, int> parse_size(const std::string& text) {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x' || w < 16 ||
        h < 16 || w > 8192 || h > 8192)
        throw cli::UsageError("--report-size must be WxH with 16..8192 pixels per side, not '" +
                              text + "'");
    return {w, h};
}

void run_eval(cli::Context& ctx) {
    if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one RESULT file");
    const bool reference_given = ctx.options().count("reference") > 0;
    const bool baseline_given = ctx.options().count("baseline") > 0;
    const bool report_given = ctx.options().count("report") > 0;
    const bool observed_given = ctx.options().count("observed") > 0;
    const bool colour_given = ctx.options().count("colour") > 0;
    if (!reference_given && !ctx.options().count("gt-poses") && !baseline_given && !report_given &&
        !ctx.options().count("points") && !observed_given && !colour_given)
        throw cli::UsageError(
            "give --reference MESH, --observed CAPTURE, --colour CAPTURE, --points STREAM, "
            "--gt-poses JSON, --baseline NAME and/or --report DIR");
    evaluation::MetricOptions options;
    std::vector<int> depths;
    double trim = 0;
    std::pair<int, int> picture_size{640, 480};
    evaluation::ObservedOptions observed_options;
    evaluation::SubjectOptions subject_options;
    cli::ObservedPeerOptions peer_options;
    std::vector<std::string> baselines;
    try {
        // In the options' millimetres (the library's checks would quote metres).
        options.taus_m.clear();
        for (double t : cli::parse_doubles(ctx.get<std::string>("tau-mm"), "tau-mm")) {
            check_range("--tau-mm", t, Range::open_closed(0, 1e6), "mm");
            options.taus_m.push_back(t / 1000.0);
        }
        const double invented_tau_mm = ctx.get<double>("invented-tau-mm");
        check_range("--invented-tau-mm", invented_tau_mm, Range::open_closed(0, 1e6), "mm");
        options.invented_tau_m = invented_tau_mm / 1000.0;
        options.samples = ctx.get<std::size_t>("samples");
        options.seed = ctx.seed();
        options.check();
        observed_options.taus_m.clear();
        for (double t :
             cli::parse_doubles(ctx.get<std::string>("observed-tau-mm"), "observed-tau-mm")) {
            check_range("--observed-tau-mm", t, Range::open_closed(0, 1e6), "mm");
            observed_options.taus_m.push_back(t / 1000.0);
        }
        observed_options.samples = options.samples;
        observed_options.seed = options.seed;
        observed_options.check();
        subject_options.radius_m = ctx.get<double>("observed-radius-m");
        check_range("--observed-radius-m", subject_options.radius_m, Range::open_closed(0, 1e3),
                    "m");
        const double voxel_mm = ctx.get<double>("tsdf-voxel-mm");
        check_range("--tsdf-voxel-mm", voxel_mm, Range::closed(0.5, 100), "mm");
        peer_options.tsdf_voxel_m = voxel_mm / 1000.0;
        peer_options.poisson_depth = ctx.get<int>("observed-poisson-depth");
        check_range("--observed-poisson-depth", peer_options.poisson_depth, Range::closed(4, 12));
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    if (baseline_given)
        baselines = cli::parse_baselines(ctx.get<std::string>("baseline"), observed_given);
    if (baseline_given && !observed_given) {
        for (double d :
             cli::parse_doubles(ctx.get<std::string>("baseline-depths"), "baseline-depths")) {
            if (!(d >= 4 && d <= 12 && d == std::floor(d)))
                throw cli::UsageError("--baseline-depths must be integers in 4..12");
            depths.push_back(static_cast<int>(d));
        }
        trim = ctx.get<double>("baseline-trim");
        if (!(trim >= 0 && trim < 0.5))
            throw cli::UsageError("--baseline-trim must be in [0, 0.5)");
    }
    peer_options.poisson_trim_quantile = ctx.get<double>("baseline-trim");
    if (!(peer_options.poisson_trim_quantile >= 0 && peer_options.poisson_trim_quantile < 0.5))
        throw cli::UsageError("--baseline-trim must be in [0, 0.5)");
    if (report_given) picture_size = parse_size(ctx.get<std::string>("report-size"));

    const std::string input = ctx.inputs().front();
    cli::LoadedResult result = cli::load_eval_input(input);
    std::optional<cli::LoadedResult> input_points;
    if (ctx.options().count("points")) {
        const std::string path = ctx.get<std::string>("points");
        input_points = cli::load_result(path);
        RGBD_CHECK(!input_points->mesh, path + ": --points must be points, not a mesh");
    } else if (!result.mesh) {
        input_points = cli::LoadedResult{};
        input_points->views = result.views;  // a cloud result is its own input
    }
    if (baseline_given && !input_points && !observed_given)
        throw cli::UsageError(
            "--baseline needs the input points: give --points STREAM or --observed CAPTURE");
    if (observed_given && !result.mesh)
        throw InputError(input + ": --observed judges a mesh; this file holds points");
    if (result.mesh && result.mesh->number_of_faces() == 0)
        throw InputError(input + ": the mesh has no faces");
    std::optional<render::Geometry> input_geometry;
    if (input_points) input_geometry = render::from_views(input_points->views);
    if (input_geometry && input_geometry->vertices.empty())
        throw InputError("the input points are empty");

    Report out = Report::object();
    out["result"] = input;
    std::optional<Mesh> reference;
    if (reference_given) {
        const std::string ref_path = ctx.get<std::string>("reference");
        reference = io::read_mesh(ref_path);
        out["reference"] = ref_path;
        out["surface"] = cli::evaluate_surface(result, *reference, options);
    }
    if (input_geometry && result.mesh)
        out["input_distance"] =
            input_distance(*result.mesh, input_geometry->vertices, options.invented_tau_m);
    evaluation::MeshQualityOptions quality_options;
    quality_options.seed = ctx.seed();
    auto mesh_quality = [&](const Mesh& mesh) {
        return evaluation::mesh_quality(mesh, input_geometry ? &input_geometry->vertices : nullptr,
                                        quality_options);
    };
    if (result.mesh) out["mesh_quality"] = mesh_quality(*result.mesh);
    // --colour: the model's surface colour against the capture's colour images.
    if (colour_given) out["colour"] = cli::colour_report(ctx, input);

    // --observed: the capture's own observations of the subject against the mesh.
    std::optional<pipeline::Observations> observations;
    std::optional<render::Geometry> observed_geometry;
    std::vector<cli::ObservedBaseline> observed_runs;
    if (observed_given) {
        {
            auto bar = ctx.progress("observations");
            observations = cli::load_observed(ctx, subject_options);
        }
        const std::vector<Eigen::Vector3d> points = observations->world_points();
        ctx.info("observed subject: " + std::to_string(points.size()) + " points (" +
                 observations->report["selection"].get<std::string>() + ")");
        Report& o = out["observed"];
        o = cli::observed_report(*result.mesh, points, observed_options);
        o["capture"] = ctx.get<std::string>("observed");
        o["subject"] = observations->report;
        if (baseline_given) {
            auto bar = ctx.progress("baselines");
            observed_runs =
                cli::run_observed_baselines(*observations, baselines, peer_options, ctx);
            for (auto& run : observed_runs) {
                run.report["observed"] = cli::observed_report(run.mesh, points, observed_options);
                if (run.mesh.number_of_faces() > 0)
                    run.report["mesh_quality"] = mesh_quality(run.mesh);
                out["baselines"][run.name] = run.report;
            }
            std::ostringstream t;
            t << "observed (tau " << observed_options.taus_m[0] * 1000 << " mm)  ours";
            for (const auto& run : observed_runs) t << "  " << run.name;
            t << "\n";
            for (const char* key : {"explained", "covered", "unsupported_area_fraction"}) {
                t << key << ": " << cell(o, key);
                for (const auto& run : observed_runs)
                    t << "  " << cell(run.report["observed"], key);
                t << "\n";
            }
            t << "time_s: -";
            for (const auto& run : observed_runs) t << "  " << cell(run.report, "time_s");
            t << "\n";
            std::cerr << t.str();
        }
        if (!input_geometry) observed_geometry = render::from_views(observations->views);
    }
    if (ctx.options().count("gt-poses")) {
        out["poses"] = cli::evaluate_poses(result.views, ctx.get<std::string>("gt-poses"),
                                           !ctx.options().count("keep-gauge"));
    }

    std::vector<BaselineRun> runs;
    int best = -1;
    if (baseline_given && !observed_given) {
        Report& b = out["baseline"];
        b["method"] = "open3d-screened-poisson";
        b["open3d"] = "0.16 (python3-open3d)";
        b["trim_quantile"] = trim;
        {
            auto bar = ctx.progress("screened poisson");
            runs = run_screened_poisson(input_points->views, depths, trim, b, ctx);
        }
        b["runs"] = Report::array();
        std::string fkey;  // the F-score at the first tau decides the best depth
        double best_score = -1;
        for (std::size_t i = 0; i < runs.size(); ++i) {
            BaselineRun& run = runs[i];
            if (reference) {
                cli::LoadedResult lr;
                lr.mesh = run.mesh;
                run.report["surface"] = cli::evaluate_surface(lr, *reference, options);
                const Report& s = run.report["surface"];
                if (fkey.empty())
                    for (auto it = s.begin(); it != s.end(); ++it)
                        if (it.key().rfind("fscore_", 0) == 0) {
                            fkey = it.key();
                            break;
                        }
                const double score = s.value(fkey, -1.0);
                if (score > best_score) best_score = score, best = static_cast<int>(i);
            }
            run.report["input_distance"] =
                input_distance(run.mesh, input_geometry->vertices, options.invented_tau_m);
            run.report["mesh_quality"] = mesh_quality(run.mesh);
            b["runs"].push_back(run.report);
        }
        if (best < 0) {  // no reference: depth 9 (the peer pipeline's choice), else the last
            best = static_cast<int>(runs.size()) - 1;
            for (std::size_t i = 0; i < runs.size(); ++i)
                if (runs[i].depth == 9) best = static_cast<int>(i);
            b["best_depth_rule"] = "depth 9 (no reference)";
        } else {
            b["best_depth_rule"] = "highest " + fkey;
        }
        b["best_depth"] = runs[best].depth;

        // Side by side on stderr.
        auto pad = [](const std::string& text, std::size_t width) {
            return std::string(width > text.size() ? width - text.size() : 0, ' ') + text;
        };
        auto group_of = [](const Report& r, const std::string& group) {
            return r.contains(group) ? r[group] : Report();
        };
        std::ostringstream t;
        t << "metric            " << pad("ours", 8);
        for (const auto& r : runs) t << pad("spr-d" + std::to_string(r.depth), 9);
        t << "\n";
        auto row = [&](const std::string& label, const std::string& group, const std::string& key,
                       double scale) {
            t << label << std::string(label.size() < 18 ? 18 - label.size() : 1, ' ')
              << pad(cell(group_of(out, group), key, scale), 8);
            for (const auto& r : runs) t << pad(cell(group_of(r.report, group), key, scale), 9);
            t << "\n";
        };
        if (reference) {
            row("chamfer mm", "surface", "chamfer_m", 1000.0);
            for (const auto& [k, v] : out["surface"].items())
                if (k.rfind("fscore_", 0) == 0) row(k, "surface", k, 1.0);
            row("invented", "surface", "invented_surface_fraction", 1.0);
            row("hausdorff p95 mm", "surface", "hausdorff_p95_m", 1000.0);
        }
        if (out.contains("input_distance")) {
            row("input dist med mm", "input_distance", "median_mm", 1.0);
            row("input dist p95 mm", "input_distance", "p95_mm", 1.0);
        }
        if (out.contains("mesh_quality")) {
            row("slivers <5deg", "mesh_quality", "sliver_fraction_5deg", 1.0);
            row("fold edges", "mesh_quality", "fold_edge_fraction", 1.0);
            row("spike vertices", "mesh_quality", "spike_vertex_fraction", 1.0);
            row("far area >3mm", "mesh_quality", "far_area_fraction_3mm", 1.0);
            row("grey vertices", "mesh_quality", "grey_vertex_fraction", 1.0);
            row("crossing pairs", "mesh_quality", "self_intersecting_pairs", 1.0);
        }
        t << "time s            " << pad("-", 8);
        for (const auto& r : runs) t << pad(cell(r.report, "time_s"), 9);
        t << "\n";
        std::cerr << t.str();
    }

    if (report_given) {
        cli::ReportPage page;
        page.title = "rgbd-eval: " + fs::path(input).filename().string();
        page.facts.push_back({"result", input});
        if (reference) page.facts.push_back({"reference", ctx.get<std::string>("reference")});
        if (ctx.options().count("points"))
            page.facts.push_back({"input", ctx.get<std::string>("points")});
        if (observed_given)
            page.facts.push_back(
                {"observed",
                 ctx.get<std::string>("observed") + ": " +
                     std::to_string(out["observed"]["subject"]["points"].get<std::size_t>()) +
                     " subject points (" +
                     out["observed"]["subject"]["selection"].get<std::string>() + ")"});
        if (baseline_given && !observed_given)
            page.facts.push_back({"baseline", "Open3D 0.16 Screened Poisson, depths " +
                                                  ctx.get<std::string>("baseline-depths") +
                                                  ", trim quantile " + trim_text(trim) +
                                                  "; best depth " +
                                                  std::to_string(runs[best].depth)});
        cli::PictureInputs pictures;
        pictures.input = input_geometry      ? &*input_geometry
                         : observed_geometry ? &*observed_geometry
                                             : nullptr;
        pictures.result = result.mesh ? &*result.mesh : nullptr;
        if (best >= 0) {
            pictures.baseline = &runs[best].mesh;
            pictures.baseline_name =
                "Open3D Screened Poisson depth " + std::to_string(runs[best].depth);
        }
        if (!observed_runs.empty()) {
            pictures.baseline = &observed_runs.back().mesh;
            pictures.baseline_name = "Open3D " + observed_runs.back().name;
        }
        pictures.reference = reference ? &*reference : nullptr;
        pictures.camera.width = picture_size.first;
        pictures.camera.height = picture_size.second;
        Report picture_info;
        {
            auto bar = ctx.progress("pictures");
            cli::render_report_pictures(pictures, page.images, picture_info);
        }
        out["report"] = picture_info;
        std::vector<std::pair<std::string, Report>> columns;
        Report ours = Report::object();
        if (out.contains("surface")) ours["surface"] = out["surface"];
        if (out.contains("input_distance")) ours["input_distance"] = out["input_distance"];
        if (out.contains("mesh_quality")) ours["mesh_quality"] = out["mesh_quality"];
        columns.push_back({"ours", ours});
        for (const auto& r : runs) columns.push_back({"SPR d" + std::to_string(r.depth), r.report});
        page.tables.push_back(cli::side_by_side("Metrics", columns));
        if (out.contains("poses"))
            page.tables.push_back(cli::side_by_side("Poses", {{"poses", out["poses"]}}));
        if (out.contains("observed")) {
            Report ours_observed = out["observed"];
            ours_observed.erase("subject");
            ours_observed.erase("capture");
            std::vector<std::pair<std::string, Report>> observed_columns{{"ours", ours_observed}};
            for (const auto& run : observed_runs) {
                Report r = run.report["observed"];
                r["peer_time_s"] = run.report.value("time_s", 0.0);
                observed_columns.push_back({"Open3D " + run.name, r});
            }
            page.tables.push_back(cli::side_by_side(
                "Observations: explained = share of the observed subject points within tau of "
                "the mesh; covered = share of the mesh area within tau of an observation; "
                "unsupported = share farther than 2 tau from every observation",
                observed_columns));
        }
        page.metrics = out;
        const fs::path dir = ctx.get<std::string>("report");
        cli::write_report(dir, page);
        ctx.note("report: " + (dir / "index.html").string());
    }
    ctx.metrics()["results"] = out;
    ctx.out() << out.dump(2) << "\n";
}

const cli::ToolSpec kSpec{
    .name = "rgbd-eval",
    .usage =
        "rgbd-eval RESULT [--reference MESH] [--observed CAPTURE] [--points STREAM] "
        "[--baseline screened-poisson|tsdf,...] [--report DIR] [options] [-o metrics.json]",
    .description =
        "Compares a result (a mesh, or a view stream / point file) with a reference surface "
        "and prints the metrics as one JSON object: Chamfer distance (mean of both directed "
        "mean distances), Hausdorff distance (max and 95th percentile), accuracy, "
        "completeness, precision, recall and F-score at each threshold tau, and the invented "
        "surface (share of the result farther than --invented-tau-mm from the reference). "
        "Distances are exact point-to-triangle distances from area-uniform samples. With "
        "--gt-poses (a capture's gt/world_from_depth.json) and a view stream as RESULT, it "
        "also reports each view's rotation and translation error. With --points (the points "
        "the result was made from), the distance of the result's vertices to them. A mesh "
        "result also gets \"mesh_quality\": shares of sliver faces (minimum angle < 5 / 10 "
        "deg, by count and area), fold edges (adjacent normals > 120 deg apart), spike "
        "vertices (a face normal > 60 deg from the vertex's area-weighted normal) and, with "
        "--points, the share of its area farther than 3 mm from every input point and of grey "
        "fill vertices (128,128,128) within 3 mm of one, and the face pairs that cross each other "
        "(self_intersecting_pairs). --baseline screened-poisson runs "
        "Open3D 0.16's Screened Poisson (Debian's python3-open3d) on the same input points at "
        "each --baseline-depths, normals as given or estimated by Open3D towards the sensors, "
        "times it, and evaluates its meshes exactly like the result, side by side (JSON and a "
        "table on stderr). --report DIR writes a page (index.html, pictures, metrics.json) "
        "with pictures of the input, the result, the best baseline depth and heat maps of the "
        "distance to the reference (else to the input points). The result is read whole.\n\n"
        "--observed CAPTURE judges a mesh against the capture's own observations (real "
        "captures without truth): every view of --frameset (a capture without frame sets: "
        "every frame, or --frames) back-projected with the capture's calibration (depth window "
        "and masks as rgbd-cloud; the poses of the capture's truth gt/world_from_depth.json "
        "when it has one, as rgbd-synth's captures do, whose rig.json poses carry a "
        "calibration error: --observed-capture-poses keeps the rig's) into the world, cut to "
        "the subject: the pixels labelled 1 in "
        "gt/<sensor>/segment/ when the capture has them, else the points inside a vertical "
        "cylinder of --observed-radius-m around where the sensors' axes converge, minus a "
        "ground plane (within 15 deg of the cameras' up; 2 cm above it dropped). \"observed\" "
        "reports, at the first --observed-tau-mm t (the others under at_<t>mm): explained "
        "(share of the subject points within t of the mesh), covered (share of the mesh area "
        "within t of an observation), unsupported_area_fraction (share farther than 2t from "
        "every observation), the areas in m^2 and counts, and the selection used. With "
        "--observed, --baseline tsdf,screened-poisson runs Open3D 0.16 on the same subject "
        "points: TSDF fusion of each view's subject depth (--tsdf-voxel-mm, truncation 4 "
        "voxels, RGB8, marching cubes) and Screened Poisson (--observed-poisson-depth, normals "
        "towards each view's camera, --baseline-trim), scored alike under \"baselines\".\n\n"
        "--colour CAPTURE renders the model into every colour camera of the frame set (z-buffer) "
        "and compares its surface colour (an .obj/.glb's texture, bilinear; else vertex colours) "
        "with the images wherever the camera sees the surface (2 px off the silhouette, "
        "viewing angle below 78 deg): \"colour\" reports PSNR (dB), mean absolute error and "
        "RMSE (levels 0-255) overall and per image.",
    .example =
        "rgbd-eval bust.ply --reference cap/gt/mesh.ply --points aligned.ply --baseline "
        "screened-poisson --report bust_report/",
    .writes_stream = false,
    .reads_stream = false,
    .writes_file = true,
    .scopes = {{{"baseline"},
                {"baseline-depths", "baseline-trim", "tsdf-voxel-mm", "observed-poisson-depth"}},
               {{"observed"}, {"baseline-depths"}, /*not_with=*/true},
               {{"colour"}, {"colour-views"}},
               {{"observed", "colour"}, {"frameset", "frames"}},
               {{"observed"},
                {"observed-tau-mm", "observed-radius-m", "z-min", "z-max", "tsdf-voxel-mm",
                 "observed-poisson-depth", "observed-capture-poses"}},
               {{"report"}, {"report-size"}},
               {{"gt-poses"}, {"keep-gauge"}}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("reference", cli::value<std::string>("MESH"),
                        "reference surface (.ply/.off/.obj), e.g. CAPTURE/gt/mesh.ply")(
            "tau-mm", cli::value<std::string>("2,5", "LIST"), "F-score thresholds in millimetres")(
            "invented-tau-mm",
            cli::value(evaluation::MetricOptions{}.invented_tau_m * 1000.0, "MM"),
            "distance beyond which result surface counts as invented")(
            "samples", cli::value(evaluation::MetricOptions{}.samples, "N"),
            "surface samples per mesh")(
            "gt-poses", cli::value<std::string>("JSON"),
            "true poses (gt/world_from_depth.json) for pose errors of a view stream")(
            "keep-gauge", "do not remove the global gauge before pose errors")(
            "points", cli::value<std::string>("STREAM"),
            "the input points of the result (view stream or point file)")(
            "baseline", cli::value<std::string>("NAME"),
            "run peers on the same input (Open3D 0.16): screened-poisson; with --observed "
            "also tsdf (a list: tsdf,screened-poisson)")(
            "baseline-depths", cli::value<std::string>("8,9,10", "LIST"),
            "octree depths of the Screened Poisson baseline")(
            "baseline-trim", cli::value<double>(0.02, "Q"),
            "drop baseline vertices below this density quantile (0 = untrimmed)")(
            "report", cli::value<std::string>("DIR"), "write a report page with pictures to DIR")(
            "observed", cli::value<std::string>("CAPTURE"),
            "judge the mesh against this capture folder's observations of the subject")(
            "frameset", cli::value<long long>(0, "N"),
            "--observed: frame set whose views are the observations (multi-sensor captures)")(
            "frames", cli::value<std::string>("A:B[:STEP]"),
            "--observed: frame positions per sensor (default: all of a capture without frame "
            "sets)")("observed-tau-mm", cli::value<std::string>("20,5", "LIST"),
                     "--observed thresholds in millimetres (the first is the main one)")(
            "observed-capture-poses",
            "--observed: place the observations with the capture's poses even when it has a "
            "truth (gt/world_from_depth.json)")(
            "observed-radius-m", cli::value(evaluation::SubjectOptions{}.radius_m, "M"),
            "--observed without labels: radius of the subject cylinder around the axes' "
            "convergence")(
            "z-min", cli::value(frames::CloudOptions{}.z_min_m, "M"),
            "--observed: depth window near limit in metres (0 = the sensor's range)")(
            "z-max", cli::value(frames::CloudOptions{}.z_max_m, "M"),
            "--observed: depth window far limit in metres (0 = the sensor's range)")(
            "tsdf-voxel-mm", cli::value(6.0, "MM"), "--baseline tsdf: voxel size")(
            "observed-poisson-depth", cli::value(9, "D"),
            "--observed --baseline screened-poisson: octree depth")(
            "report-size", cli::value<std::string>("640x480", "WxH"),
            "size of each report picture, WxH")(
            "colour", cli::value<std::string>("CAPTURE"),
            "PSNR and mean absolute error of the model's surface colour (texture of an .obj/.glb, "
            "else vertex colours) against this capture's colour images")(
            "colour-views", cli::value<std::string>("ALIGNED.ply"),
            "--colour: frames and refined poses of these aligned views (default: the capture's "
            "truth gt/world_from_depth.json when present, else its own poses)");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_eval); }
