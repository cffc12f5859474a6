// rgbd-clean: noise removal on a view stream.
#include "algorithms/denoise/statistical_outliers.hpp"
#include "cli/common/tool.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-clean";
    spec.usage = "rgbd-clean [--statistical | --radius] [options] [FILE...] > cleaned.ply";
    spec.description =
        "Removes noise points from every view of a stream, one view at a time. --statistical "
        "(the default) is statistical outlier removal with the exact semantics of Open3D's "
        "remove_statistical_outlier (or PCL's StatisticalOutlierRemoval with --convention pcl): "
        "a point goes when its mean distance to its k nearest neighbours exceeds the mean of that "
        "value over the view plus --std-ratio standard deviations. --radius removes points with "
        "too few neighbours within a radius given in metres or as a multiple of the view's "
        "robust point spacing. --mark flags points (property noise = 1) instead of deleting them.";
    spec.example =
        "rgbd-cloud cap/ | rgbd-clean --statistical --k 20 --std-ratio 2 | rgbd-align | rgbd-mesh "
        "-o bust.ply";
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("statistical", "statistical outlier removal (default)")(
            "radius", "radius outlier removal")(
            "k", cli::po::value<int>()->default_value(20)->value_name("N"),
            "--statistical: neighbours per point")(
            "std-ratio", cli::po::value<double>()->default_value(2.0)->value_name("X"),
            "--statistical: standard deviations above the mean distance that are kept")(
            "convention",
            cli::po::value<std::string>()->default_value("open3d")->value_name("NAME"),
            "open3d (neighbours include the point itself) or pcl semantics")(
            "min-points", cli::po::value<int>()->default_value(16)->value_name("N"),
            "--radius: minimum neighbours within the radius")(
            "radius-m", cli::po::value<double>()->value_name("M"), "--radius: radius in metres")(
            "radius-spacing", cli::po::value<double>()->default_value(4.0)->value_name("X"),
            "--radius: radius as a multiple of the robust point spacing (when --radius-m is not "
            "given)")("mark", "flag noise points (noise = 1) instead of deleting them");
    };
    return cli::run_tool(argc, argv, spec, [&](cli::Context& ctx) {
        const bool radius = ctx.options().count("radius") > 0;
        if (radius && ctx.options().count("statistical"))
            throw cli::UsageError("choose one of --statistical and --radius");
        denoise::StatisticalOptions statistical;
        denoise::RadiusOptions radius_options;
        try {
            statistical.k = ctx.get<int>("k");
            statistical.std_ratio = ctx.get<double>("std-ratio");
            const std::string convention = ctx.get<std::string>("convention");
            if (convention == "open3d")
                statistical.convention = denoise::OutlierConvention::kOpen3d;
            else if (convention == "pcl")
                statistical.convention = denoise::OutlierConvention::kPcl;
            else
                throw cli::UsageError("--convention must be open3d or pcl");
            statistical.mark = ctx.options().count("mark") > 0;
            radius_options.min_points = ctx.get<int>("min-points");
            if (ctx.options().count("radius-m"))
                radius_options.radius_m = ctx.get<double>("radius-m");
            else
                radius_options.radius_spacing_factor = ctx.get<double>("radius-spacing");
            radius_options.mark = statistical.mark;
            radius_options.convention = statistical.convention;
            if (radius)
                radius_options.check();
            else
                statistical.check();
        } catch (const InputError& e) {
            throw cli::UsageError(e.what());
        }
        auto bar = ctx.progress("clean");
        ctx.for_each_document([&](io::Document& document) {
            if (document.kind != io::DocumentKind::kPoints) {
                ctx.warn("document " + std::to_string(document.cloud.view.id) +
                         " is a mesh; passed through");
                ctx.write(document);
                return;
            }
            if (document.cloud.empty())
                ctx.warn("view " + std::to_string(document.cloud.view.id) + " has no points");
            Report report = radius ? denoise::remove_radius_outliers(document.cloud, radius_options,
                                                                     bar.callback())
                                   : denoise::remove_statistical_outliers(
                                         document.cloud, statistical, bar.callback());
            report["view"] = document.cloud.view.id;
            ctx.add_document_metrics(report);
            ctx.info("view " + std::to_string(document.cloud.view.id) + ": " + report.dump());
            ctx.write(document);
        });
    });
}
