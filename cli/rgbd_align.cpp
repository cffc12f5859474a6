// rgbd-align: multi-view registration of a view stream.
#include "algorithms/sampling/merge_views.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-align";
    spec.usage = "rgbd-align [options] [FILE...] > aligned.ply";
    spec.description =
        "Registers all views of a stream into one world frame. Each view starts from the pose in "
        "its metadata (the rig's calibration or a per-frame pose); normals are estimated per view "
        "and oriented towards its sensor; then every view is refined by point-to-plane ICP "
        "(robust weights, distance and normal gates, coarse to fine) against all the other views "
        "at once, for several rounds, with --fixed-view holding the gauge. Each view gets a "
        "verdict (PASS / WARN / FAIL from its overlap and residual, and from how far it moved), "
        "printed on stderr and in --metrics. Output: the views in the world frame with their "
        "refined poses, or one merged view with --merge.";
    spec.example =
        "rgbd-cloud cap/ | rgbd-clean | rgbd-align --merge --metrics align.json -o merged.ply";
    spec.whole_stream = true;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("merge", "emit one merged view instead of one document per view")(
            "fixed-view", cli::po::value<int>()->default_value(0)->value_name("I"),
            "position in the stream of the view that holds the gauge")(
            "rounds", cli::po::value<int>()->default_value(4)->value_name("N"),
            "rounds of joint refinement")(
            "voxel-m", cli::po::value<double>()->default_value(0.0)->value_name("M"),
            "voxel size for the registration copies (0 = from the point spacing)");
    };
    return cli::run_tool(argc, argv, spec, [&](cli::Context& ctx) {
        registration::MultiViewOptions options;
        try {
            if (ctx.get<int>("fixed-view") < 0) throw cli::UsageError("--fixed-view must be >= 0");
            options.fixed_view = static_cast<std::size_t>(ctx.get<int>("fixed-view"));
            options.rounds = ctx.get<int>("rounds");
            options.voxel_m = ctx.get<double>("voxel-m");
            options.check();
        } catch (const InputError& e) {
            throw cli::UsageError(e.what());
        }
        std::vector<PointCloud> views = cli::read_point_views(ctx);
        if (options.fixed_view >= views.size())
            throw cli::UsageError("--fixed-view " + std::to_string(options.fixed_view) +
                                  " but the stream has " + std::to_string(views.size()) + " views");
        auto bar = ctx.progress("align");
        Report report = cli::align_stage(views, options, bar.callback());
        for (const auto& v : report["views"]) {
            const std::string line =
                "view " + std::to_string(v["view"].get<int>()) + " (" +
                v["sensor"].get<std::string>() + "): " + v["verdict"].get<std::string>() +
                ", fitness " + std::to_string(v["fitness"].get<double>()) + ", rmse " +
                std::to_string(v["inlier_rmse_m"].get<double>() * 1000) + " mm, moved " +
                std::to_string(v["rotation_change_deg"].get<double>()) + " deg / " +
                std::to_string(v["translation_change_m"].get<double>() * 1000) + " mm";
            if (v["verdict"] == "PASS")
                ctx.info(line);
            else
                ctx.warn(line);
        }
        ctx.metrics()["align"] = report;
        if (ctx.options().count("merge")) {
            io::Document merged;
            merged.cloud = sampling::merge_views(std::move(views));
            ctx.write(merged);
        } else {
            for (auto& view : views) {
                io::Document document;
                document.cloud = std::move(view);
                ctx.write(document);
            }
        }
    });
}
