// rgbd-eval: metrics of a reconstructed mesh or cloud (and of estimated poses) against ground
// truth.
#include <filesystem>
#include <iostream>

#include "algorithms/evaluation/metrics.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-eval";
    spec.usage = "rgbd-eval RESULT --reference MESH [options] [-o metrics.json]";
    spec.description =
        "Compares a result (a mesh, or a view stream / point file) with a reference surface and "
        "prints the metrics as one JSON object: Chamfer distance (mean of both directed mean "
        "distances), Hausdorff distance (max and 95th percentile), accuracy, completeness, "
        "precision, recall and F-score at each threshold tau, and the invented surface (share "
        "of the result farther than --invented-tau-mm from the reference). Distances are exact "
        "point-to-triangle distances from area-uniform samples. With --gt-poses (a capture's "
        "gt/world_from_depth.json) and a view stream as RESULT, it also reports each view's "
        "rotation and translation error. The result is read whole.";
    spec.example = "rgbd-eval bust.ply --reference cap/gt/mesh.ply --tau-mm 2,5 -o metrics.json";
    spec.writes_stream = false;
    spec.reads_stream = false;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("reference", cli::po::value<std::string>()->value_name("MESH"),
                        "reference surface (.ply/.off/.obj), e.g. CAPTURE/gt/mesh.ply")(
            "tau-mm", cli::po::value<std::string>()->default_value("2,5")->value_name("LIST"),
            "F-score thresholds in millimetres")(
            "invented-tau-mm", cli::po::value<double>()->default_value(5.0)->value_name("MM"),
            "distance beyond which result surface counts as invented")(
            "samples", cli::po::value<std::size_t>()->default_value(200000)->value_name("N"),
            "surface samples per mesh")(
            "gt-poses", cli::po::value<std::string>()->value_name("JSON"),
            "true poses (gt/world_from_depth.json) for pose errors of a view stream")(
            "keep-gauge", "do not remove the global gauge before pose errors");
    };
    return cli::run_tool(argc, argv, spec, [&](cli::Context& ctx) {
        if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one RESULT file");
        if (!ctx.options().count("reference") && !ctx.options().count("gt-poses"))
            throw cli::UsageError("give --reference MESH and/or --gt-poses JSON");
        evaluation::MetricOptions options;
        try {
            options.taus_m.clear();
            for (double t : cli::parse_doubles(ctx.get<std::string>("tau-mm"), "tau-mm"))
                options.taus_m.push_back(t / 1000.0);
            options.invented_tau_m = ctx.get<double>("invented-tau-mm") / 1000.0;
            options.samples = ctx.get<std::size_t>("samples");
            options.seed = ctx.seed();
            options.check();
        } catch (const InputError& e) {
            throw cli::UsageError(e.what());
        }
        const std::string input = ctx.inputs().front();
        cli::LoadedResult result = cli::load_result(input);
        Report out = Report::object();
        out["result"] = input;
        if (ctx.options().count("reference")) {
            const std::string ref_path = ctx.get<std::string>("reference");
            const Mesh reference = io::read_mesh(ref_path);
            out["reference"] = ref_path;
            out["surface"] = cli::evaluate_surface(result, reference, options);
        }
        if (ctx.options().count("gt-poses")) {
            out["poses"] = cli::evaluate_poses(result.views, ctx.get<std::string>("gt-poses"),
                                               !ctx.options().count("keep-gauge"));
        }
        ctx.metrics()["results"] = out;
        ctx.out() << out.dump(2) << "\n";
    });
}
