// rgbd-clean: noise removal on a view stream.
#include <memory>
#include <string>
#include <vector>

#include "algorithms/denoise/density_outliers.hpp"
#include "algorithms/denoise/depth_smoothing.hpp"
#include "algorithms/denoise/distance_outliers.hpp"
#include "algorithms/denoise/statistical_outliers.hpp"
#include "cli/common/tool.hpp"
#include "pipeline/stages.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

enum class Method { kAuto, kDistance, kDensity, kStatistical, kRadius };

void run_clean(cli::Context& ctx) {
    const auto& vm = ctx.options();
    std::vector<Method> chosen;
    if (vm.count("distance")) chosen.push_back(Method::kDistance);
    if (vm.count("density")) chosen.push_back(Method::kDensity);
    if (vm.count("statistical")) chosen.push_back(Method::kStatistical);
    if (vm.count("radius")) chosen.push_back(Method::kRadius);
    if (chosen.size() > 1)
        throw cli::UsageError("choose one of --distance, --density, --statistical and --radius");
    const Method method = chosen.empty() ? Method::kAuto : chosen.front();

    const bool mark = vm.count("mark") > 0;
    const bool smooth = vm.count("smooth") > 0;
    if (smooth && method != Method::kAuto && method != Method::kDistance)
        throw cli::UsageError(
            "--smooth works per organised view with --distance (before alignment)");
    denoise::StatisticalOptions statistical;
    denoise::RadiusOptions radius_options;
    denoise::DistanceOptions distance;
    denoise::DensityOptions density;
    denoise::SmoothOptions smoothing;
    bool noise_given = false;  // else each view's (or the stream's) own, rgbd-cloud's tag
    try {
        const bool has_k = vm.count("k") > 0;
        if (has_k) statistical.k = distance.k = density.k = ctx.get<int>("k");
        statistical.std_ratio = ctx.get<double>("std-ratio");
        const std::string convention = ctx.get<std::string>("convention");
        if (convention == "open3d")
            statistical.convention = denoise::OutlierConvention::kOpen3d;
        else if (convention == "pcl")
            statistical.convention = denoise::OutlierConvention::kPcl;
        else
            throw cli::UsageError("--convention must be open3d or pcl");
        statistical.mark = mark;
        radius_options.min_points = ctx.get<int>("min-points");
        if (vm.count("radius-m"))
            radius_options.radius_m = ctx.get<double>("radius-m");
        else
            radius_options.radius_spacing_factor = ctx.get<double>("radius-spacing");
        radius_options.mark = mark;
        radius_options.convention = statistical.convention;

        const std::string noise_name = ctx.get<std::string>("noise-model");
        if (noise_name != "auto") {
            const auto model = denoise::parse_noise_model(noise_name);
            distance.noise_model = density.noise_model = smoothing.noise_model = model;
            noise_given = true;
        }
        if (vm.count("theta-max-deg"))
            distance.theta_max_deg = density.theta_max_deg = ctx.get<double>("theta-max-deg");
        // --high-recall sets its operating point; options given explicitly still win.
        if (vm.count("high-recall")) distance.use_high_recall();
        const auto given = [&](const char* name) {
            return vm.count(name) && (!vm[name].defaulted() || !vm.count("high-recall"));
        };
        if (given("c-min")) distance.c_min = ctx.get<int>("c-min");
        if (given("line-sigmas")) distance.line_sigmas = ctx.get<double>("line-sigmas");
        if (given("dense-min")) distance.dense_min = ctx.get<int>("dense-min");
        if (given("c-min-wide")) distance.c_min_wide = ctx.get<int>("c-min-wide");
        if (given("keep-knn")) distance.keep_knn = ctx.get<double>("keep-knn");
        distance.keep_k = ctx.get<int>("keep-k");
        distance.n_speckle = ctx.get<int>("n-speckle");
        distance.alpha = ctx.get<double>("alpha");
        distance.pass_a = vm.count("no-pass-a") == 0;
        distance.pass_b = vm.count("knn-test") != 0;
        distance.mark = mark;
        if (vm.count("beta")) density.beta = density.beta_local = ctx.get<double>("beta");
        const auto reference = denoise::density_reference_of(ctx.get<std::string>("reference"));
        if (!reference) throw cli::UsageError("--reference must be auto, sensors or local");
        density.reference = *reference;
        density.consensus_ratio = ctx.get<double>("consensus-ratio");
        density.consensus_sigmas = ctx.get<double>("consensus-sigmas");
        density.cluster_spacing = ctx.get<double>("cluster-spacing");
        density.min_cluster_fraction = ctx.get<double>("min-cluster-fraction");
        density.judge_synthetic = vm.count("judge-synthetic") != 0;
        density.seed = ctx.seed();
        density.mark = mark;
        // Every option is validated whatever the method, so a typo never passes silently.
        statistical.check();
        radius_options.check();
        distance.check();
        smoothing.check();
        if (method == Method::kDensity || has_k) density.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }

    if (method == Method::kDensity) {
        std::vector<io::Document> documents = ctx.read_all_documents();
        auto bar = ctx.progress("clean");
        std::vector<PointCloud> views;
        std::vector<std::size_t> slots;
        for (std::size_t d = 0; d < documents.size(); ++d)
            if (documents[d].kind == io::DocumentKind::kPoints) {
                views.push_back(std::move(documents[d].cloud));
                slots.push_back(d);
            }
        if (!noise_given) density.noise_model = pipeline::stream_noise_model(views);
        Report report = denoise::remove_density_outliers(views, density, bar.callback());
        ctx.add_document_metrics(report);
        ctx.info("density: " + report.dump());
        for (std::size_t v = 0; v < views.size(); ++v)
            documents[slots[v]].cloud = std::move(views[v]);
        for (auto& document : documents) {
            if (document.kind == io::DocumentKind::kPoints)
                ctx.write(document);
            else
                ctx.pass_through(document);
        }
        return;
    }

    bool fallback_noted = false;
    std::unique_ptr<cli::ProgressBar> bar;  // from the first view on: bad input fails without it
    ctx.for_each_view([&](PointCloud& cloud) {
        if (!bar) bar.reset(new cli::ProgressBar(ctx.progress("clean")));
        if (cloud.empty()) ctx.warn("view " + std::to_string(cloud.view.id) + " has no points");
        Method use = method;
        if (use == Method::kAuto) {
            use = cloud.view.has_grid() && cloud.pixel_map() ? Method::kDistance
                                                             : Method::kStatistical;
            if (use == Method::kStatistical && !fallback_noted && !cloud.empty()) {
                ctx.note("view " + std::to_string(cloud.view.id) +
                         " has no pixel grid: using --statistical (give --density after "
                         "alignment for the adaptive filter)");
                fallback_noted = true;
            }
        }
        if (!noise_given)
            distance.noise_model = smoothing.noise_model =
                pipeline::view_noise_model(cloud).value_or(denoise::NoiseModel::kKinectV2);
        Report report;
        switch (use) {
            case Method::kDistance:
                report = denoise::remove_distance_outliers(cloud, distance, bar->callback());
                break;
            case Method::kRadius:
                report = denoise::remove_radius_outliers(cloud, radius_options, bar->callback());
                break;
            default:
                report = denoise::remove_statistical_outliers(cloud, statistical, bar->callback());
                break;
        }
        // Throws naming the view when it has no grid (--statistical fallback).
        if (smooth) report["smooth"] = denoise::smooth_depth(cloud, smoothing);
        report["view"] = cloud.view.id;
        ctx.add_document_metrics(report);
        ctx.info("view " + std::to_string(cloud.view.id) + ": " + report.dump());
    });
}

const cli::ToolSpec kSpec{
    .name = "rgbd-clean",
    .usage =
        "rgbd-clean [--distance | --density | --statistical | --radius] [options] [FILE...] > "
        "cleaned.ply",
    .description =
        "Removes noise points from a view stream, or from plain point-cloud files (.pcd, .xyz, "
        ".pwn; a .ply file is a stream), each read as one unorganised view. --distance (the "
        "default for organised views, i.e. views with a pixel grid, straight from rgbd-cloud; "
        "before alignment) works per view: a pixel with fewer than --c-min neighbours in its "
        "5x5 window (and fewer than --c-min-wide in its 7x7 window) that a real surface at "
        "--theta-max-deg plus 3 sigma of the sensor noise can explain is a flying pixel, so is "
        "a pixel inside a dense window that continues no straight depth line (within "
        "--line-sigmas sigma) along any grid axis, unless its nearest 3D points in the 7x7 "
        "window lie within --keep-knn pixel footprints; small grid components are speckles; "
        "--smooth then moves every surviving point along its ray onto the plane (in inverse "
        "depth) fitted to the same-surface pixels of its 5x5 window (edge-aware: neighbours "
        "beyond 3 sigma of the sensor noise are another surface), deleting nothing; --knn-test "
        "adds a kNN distance test relative to the pixel footprint z/f. Every threshold scales "
        "with depth and the noise model. --density (after alignment: run on the aligned views "
        "of rgbd-align without --merge; reads the whole stream) judges every point over all "
        "views together: its measured density against what the views that see it should have "
        "produced (1/(z/f)^2 per view, occlusion-aware); a point below --consensus-ratio of it "
        "that its own view sees steeper than --theta-max-deg and that lies more than "
        "--consensus-sigmas sigma off the other views' surface is a flying pixel too; then it "
        "drops small detached clusters (linking the measured points; a super-resolved point goes "
        "with the measured point it was made from); views without cameras (merged or unorganised "
        "clouds) "
        "are compared with the local median density instead. Views without a grid fall back to "
        "--statistical when no method is given. --statistical is statistical outlier removal "
        "with the exact semantics of Open3D's remove_statistical_outlier (or PCL's with "
        "--convention pcl); --radius removes points with too few neighbours within a radius "
        "given in metres or as a multiple of the view's robust point spacing. --mark flags "
        "points (property noise = 1) instead of deleting them.",
    .example =
        "rgbd-cloud cap/ | rgbd-clean --distance | rgbd-align | rgbd-clean --density | "
        "rgbd-mesh -o bust.ply",
    .reads_cloud_files = true,
    .ranges = {{"radius-m", Range::open_closed(0, 100), "m"}},
    // --distance and --statistical are the defaults (organised views / the others), so their
    // options are refused only next to another mode; --density's and --radius's need theirs.
    .scopes = {{{"density"},
                {"beta", "reference", "consensus-ratio", "consensus-sigmas", "cluster-spacing",
                 "min-cluster-fraction", "judge-synthetic"}},
               {{"radius"}, {"min-points", "radius-m", "radius-spacing"}},
               {{"distance", "density", "radius"}, {"std-ratio"}, /*not_with=*/true},
               {{"distance", "density"}, {"convention"}, /*not_with=*/true},
               {{"statistical", "radius"}, {"noise-model", "theta-max-deg"}, /*not_with=*/true},
               {{"radius"}, {"k"}, /*not_with=*/true},
               {{"density", "statistical", "radius"},
                {"c-min", "c-min-wide", "line-sigmas", "dense-min", "keep-knn", "keep-k",
                 "n-speckle", "alpha", "no-pass-a", "knn-test", "high-recall"},
                /*not_with=*/true}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("distance",
                        "adaptive distance-based removal per organised view (default when the "
                        "view has a grid)")(
            "density", "adaptive density-based removal over all aligned views")(
            "statistical", "statistical outlier removal (default for views without a grid)")(
            "radius", "radius outlier removal")(
            "k", cli::value<int>("N"),
            cli::with_numbers(
                "neighbours per point (default {} for --statistical, {} for "
                "--density, {} for --distance)",
                {double(denoise::StatisticalOptions{}.k), double(denoise::DensityOptions{}.k),
                 double(denoise::DistanceOptions{}.k)})
                .c_str())(
            "std-ratio", cli::value(denoise::StatisticalOptions{}.std_ratio, "X"),
            "--statistical: standard deviations above the mean distance that are kept")(
            "convention", cli::value<std::string>("open3d", "NAME"),
            "--statistical/--radius: open3d (neighbours include the point itself) or pcl")(
            "min-points", cli::value(denoise::RadiusOptions{}.min_points, "N"),
            "--radius: minimum neighbours within the radius")("radius-m", cli::value<double>("M"),
                                                              "--radius: radius in metres")(
            "radius-spacing", cli::value(denoise::RadiusOptions{}.radius_spacing_factor, "X"),
            "--radius: radius as a multiple of the robust point spacing (when --radius-m is "
            "not given)")(
            "noise-model", cli::value<std::string>("auto", "NAME"),
            "--distance/--density: sensor noise model kinect_v2, kinect_v1, sr300 or "
            "generic; auto: the one the views' metadata names (rgbd-cloud writes the rig "
            "sensor's; --density: when all views agree), else kinect_v2")(
            "theta-max-deg", cli::value<double>("DEG"),
            cli::with_numbers(
                "--distance/--density: steepest incidence angle of a real "
                "surface (default {} for --distance, {} for --density)",
                {denoise::DistanceOptions{}.theta_max_deg, denoise::DensityOptions{}.theta_max_deg})
                .c_str())("c-min", cli::value(denoise::DistanceOptions{}.c_min, "N"),
                          "--distance: supporting neighbours a pixel needs in its 5x5 window")(
            "c-min-wide", cli::value(denoise::DistanceOptions{}.c_min_wide, "N"),
            "--distance: a pixel short of --c-min keeps its support with N supporting "
            "neighbours in its 7x7 window (0 = the 5x5 window only)")(
            "line-sigmas", cli::value(denoise::DistanceOptions{}.line_sigmas, "X"),
            "--distance: line-support tolerance in sigma of the sensor noise (0 = no line "
            "test)")(
            "dense-min", cli::value(denoise::DistanceOptions{}.dense_min, "N"),
            "--distance: the line test applies where at least N of the 24 window pixels are "
            "valid")("keep-knn", cli::value(denoise::DistanceOptions{}.keep_knn, "X"),
                     "--distance: keep a pixel the support or line test flags when its "
                     "--keep-k nearest points in its 7x7 window lie within X pixel footprints "
                     "z/f on average (0 = off)")("keep-k",
                                                 cli::value(denoise::DistanceOptions{}.keep_k, "N"),
                                                 "--distance: neighbours of the --keep-knn test")(
            "n-speckle", cli::value(denoise::DistanceOptions{}.n_speckle, "N"),
            "--distance: grid components with fewer pixels are speckles (0 = off)")(
            "alpha", cli::value(denoise::DistanceOptions{}.alpha, "X"),
            "--distance: robust standard deviations of the normalised kNN distance that are "
            "kept")("no-pass-a", "--distance: skip the grid support and speckle tests")(
            "knn-test", "--distance: add the normalised kNN distance test (--k, --alpha)")(
            "beta", cli::value<double>("X"),
            cli::with_numbers(
                "--density: keep a point when its density is at least X times the "
                "expected one (default {} against the sensors' expectation, {} "
                "against the local median)",
                {denoise::DensityOptions{}.beta, denoise::DensityOptions{}.beta_local})
                .c_str())(
            "reference", cli::value<std::string>("auto", "NAME"),
            "--density: expected density from the sensors (views' cameras), local (median of "
            "the neighbours) or auto")(
            "consensus-ratio", cli::value(denoise::DensityOptions{}.consensus_ratio, "X"),
            "--density: consensus test on points below X times their expected density that "
            "their own view sees steeper than --theta-max-deg (0 = no consensus test)")(
            "consensus-sigmas", cli::value(denoise::DensityOptions{}.consensus_sigmas, "X"),
            "--density: such a point is noise when farther than X sigma of the sensor noise "
            "from the plane of the other views' points around it")(
            "cluster-spacing", cli::value(denoise::DensityOptions{}.cluster_spacing, "X"),
            "--density: cluster link distance as a multiple of the robust spacing (0 = no "
            "cluster pass)")(
            "min-cluster-fraction", cli::value(denoise::DensityOptions{}.min_cluster_fraction, "X"),
            "--density: detached clusters smaller than this share of the points are removed")(
            "judge-synthetic",
            "--density: judge super-resolved points (rgbd-upsample's) wholly on their own; by "
            "default each is judged on its own count against the expected density of the "
            "measured point it was made from, and takes that point's verdict in the cluster pass")(
            "mark", "flag noise points (noise = 1) instead of deleting them")(
            "high-recall",
            "--distance: the recall operating point (--c-min 4 --c-min-wide 0 --keep-knn 0 "
            "--line-sigmas 2 --dense-min 12; explicit options win): removes more flying pixels "
            "at the price of some surface (rgbd-synth rings: 97% of the flying pixels, "
            "0.8-1.3% of the surface, against 92-93% and 0.06-0.12% by default)")(
            "smooth",
            "--distance: then smooth the surviving depths along the pixel rays (edge-aware "
            "plane fit over the 5x5 window; points move, none is deleted)");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_clean); }
