// rgbd-align: multi-view registration of a view stream.
#include "algorithms/registration/duplicate_removal.hpp"
#include "algorithms/sampling/merge_views.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

void run_align(cli::Context& ctx) {
    registration::MultiViewOptions options;
    pipeline::StandMode stand = pipeline::StandMode::kAuto;
    try {
        if (ctx.get<int>("fixed-view") < 0) throw cli::UsageError("--fixed-view must be >= 0");
        options.fixed_view = static_cast<std::size_t>(ctx.get<int>("fixed-view"));
        options.rounds = ctx.get<int>("rounds");
        options.voxel_m = ctx.get<double>("voxel-m");
        options.pairwise = !ctx.options().count("no-pairwise");
        options.global_registration = !ctx.options().count("no-global");
        options.colour_weight = ctx.get<double>("colour-weight");
        options.ransac_iterations = ctx.get<int>("ransac-iterations");
        options.max_prior_rotation_deg = ctx.get<double>("max-prior-rotation-deg");
        options.calibration_prior_rotation_deg = ctx.get<double>("calibration-prior-deg");
        options.calibration_prior_translation_m = ctx.get<double>("calibration-prior-mm") / 1000.0;
        if ((options.calibration_prior_rotation_deg > 0) !=
            (options.calibration_prior_translation_m > 0))
            throw cli::UsageError(
                "--calibration-prior-deg and --calibration-prior-mm must both be positive, or "
                "both 0 (off)");
        options.seed = ctx.seed();
        options.check();
        stand = pipeline::parse_stand_mode(ctx.get<std::string>("stand"));
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    std::vector<PointCloud> views = cli::read_point_views(ctx);
    if (options.fixed_view >= views.size())
        throw cli::UsageError("--fixed-view " + std::to_string(options.fixed_view) +
                              " but the stream has " + std::to_string(views.size()) + " views");
    if (ctx.options().count("ignore-poses"))
        for (PointCloud& view : views) {
            if (view.view.frame == ViewFrame::kWorld && view.view.world_from_sensor)
                transform(view, view.view.world_from_sensor->inverse());
            view.view.frame = ViewFrame::kSensor;
            view.view.world_from_sensor = Pose::Identity();
        }
    auto bar = ctx.progress("align");
    Report report = cli::align_stage(views, options, bar.callback());
    // A line per pair and per view: PASS only with -v, WARN and FAIL always.
    const auto say = [&](const Report& r, const std::string& who, const std::string& more) {
        const std::string line =
            who + ": " + r["verdict"].get<std::string>() +
            (r.contains("reason") ? " (" + r["reason"].get<std::string>() + ")" : "") +
            cli::formatted(", fitness %.3f, rmse %.2f mm, ", r["fitness"].get<double>(),
                           r["inlier_rmse_m"].get<double>() * 1000) +
            more;
        if (r["verdict"] == "PASS")
            ctx.info(line);
        else
            ctx.warn(line);
    };
    for (const auto& p : report["pairs"])
        say(p,
            "pair " + std::to_string(p["target"].get<int>()) + "-" +
                std::to_string(p["source"].get<int>()),
            "start " + p["method"].get<std::string>() +
                cli::formatted(", off the ring %.2f deg / %.1f mm",
                               p["ring_rotation_deg"].get<double>(),
                               p["ring_translation_m"].get<double>() * 1000));
    if (report.contains("loop_closure")) {
        const auto& l = report["loop_closure"];
        ctx.info(cli::formatted(
            "loop closure: %.2f deg / %.1f mm chained, %.2f deg / %.1f mm after "
            "the pose graph and joint rounds",
            l["before_rotation_deg"].get<double>(), l["before_translation_m"].get<double>() * 1000,
            l["after_rotation_deg"].get<double>(), l["after_translation_m"].get<double>() * 1000));
    }
    for (const auto& v : report["views"])
        say(v,
            "view " + std::to_string(v["view"].get<int>()) + " (" + v["sensor"].get<std::string>() +
                ")",
            cli::formatted("moved %.2f deg / %.1f mm", v["rotation_change_deg"].get<double>(),
                           v["translation_change_m"].get<double>() * 1000));
    ctx.metrics()["align"] = report;
    if (pipeline::stand_applies(views, stand)) {
        auto stand_bar = ctx.progress("stand");
        const Report removed =
            pipeline::stand_stage(views, stand, segment::StandOptions{}, stand_bar.callback());
        ctx.metrics()["stand"] = removed;
        if (removed.contains("note")) ctx.info(removed["note"].get<std::string>());
        if (removed.contains("removed"))
            ctx.info("stand: " + std::to_string(removed["removed"].get<std::size_t>()) +
                     " points removed");
    }
    if (ctx.options().count("merge")) {
        io::Document merged;
        if (ctx.options().count("keep-duplicates")) {
            merged.cloud = sampling::merge_views(std::move(views));
        } else {
            registration::DuplicateReport dup;
            auto merge_bar = ctx.progress("merge");
            merged.cloud = registration::merge_without_duplicates(std::move(views), {}, &dup,
                                                                  merge_bar.callback());
            ctx.metrics()["merge"] = dup.to_json();
            ctx.info("merge: " + std::to_string(dup.input) + " points, " +
                     std::to_string(dup.duplicates) + " duplicates and " +
                     std::to_string(dup.replaced) + " worse observations dropped, " +
                     std::to_string(dup.output) + " kept");
        }
        ctx.write(merged);
    } else {
        for (auto& view : views) {
            io::Document document;
            document.cloud = std::move(view);
            ctx.write(document);
        }
    }
}

const cli::ToolSpec kSpec{
    .name = "rgbd-align",
    .usage = "rgbd-align [options] [FILE...] > aligned.ply",
    .description =
        "Registers all views of a stream into one world frame. Each view starts from the pose "
        "in its metadata (the rig's calibration or a per-frame pose, or none with "
        "--ignore-poses). 1. Pairs: every view with its nearest views by viewing direction "
        "(ring neighbours), or consecutive views and the last-first pair when the directions "
        "are unknown (a turntable or walk-around sequence). Each pair is registered by "
        "point-to-plane ICP with a colour term (robust weights, distance and normal gates, "
        "coarse to fine) from the initial pose, and from an FPFH + RANSAC hypothesis when the "
        "initial pose did not settle the pair (no poses or all alike, or its result left the "
        "calibration's bounds or would not pass; results that leave the bounds are discarded; "
        "on a ring the loop picks between the two). 2. A pose graph spreads the loop error and "
        "prunes pairs that disagree with "
        "the ring. 3. Joint rounds refine all views against all others at once, --fixed-view "
        "holding the gauge. Every pair and every view gets a verdict (PASS / WARN / FAIL with "
        "overlap, residual and agreement with the ring), and a ring its loop-closure error "
        "before and after, on stderr and in --metrics. Deterministic for a --seed and any "
        "--threads. On turntable streams the stand below the object is then removed "
        "(--stand). Output: the views in the world frame with their refined poses, or one "
        "merged view with --merge.",
    .example =
        "rgbd-cloud cap/ | rgbd-clean | rgbd-align --merge --metrics align.json -o merged.ply",
    .whole_stream = true,
    .ranges = {{"max-prior-rotation-deg", Range::closed(0, 360), "degrees"},
               {"calibration-prior-deg", Range::closed(0, 90), "degrees"},
               {"calibration-prior-mm", Range::closed(0, 1000), "mm"}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("merge",
                        "emit one merged view instead of one document per view, without "
                        "duplicates: a point with an earlier view's point within 1 spacing is "
                        "dropped when their colours agree (Delta E <= 15), else the better "
                        "observed of the two (nearer, more head-on) stays")(
            "keep-duplicates", "with --merge: plain concatenation of the views")(
            "fixed-view",
            cli::value(static_cast<int>(registration::MultiViewOptions{}.fixed_view), "I"),
            "position in the stream of the view that holds the gauge")(
            "rounds", cli::value(registration::MultiViewOptions{}.rounds, "N"),
            "rounds of joint refinement")(
            "voxel-m", cli::value(registration::MultiViewOptions{}.voxel_m, "M"),
            "voxel size for the registration copies (0 = from the point spacing)")(
            "ignore-poses",
            "start every view from its own sensor frame (poses unknown); pairs follow the "
            "stream order and the result is in the first view's frame")(
            "no-pairwise", "skip the pairwise stage and the pose graph (joint rounds only)")(
            "no-global", "no FPFH + RANSAC hypotheses (trust the initial poses' basin)")(
            "colour-weight", cli::value(registration::MultiViewOptions{}.colour_weight, "W"),
            "weight of the colour term (0 = geometry only)")(
            "ransac-iterations",
            cli::value(registration::MultiViewOptions{}.ransac_iterations, "N"),
            "RANSAC hypotheses per pair")(
            "max-prior-rotation-deg",
            cli::value(registration::MultiViewOptions{}.max_prior_rotation_deg, "D"),
            "pair results farther than this from the initial relative pose are discarded (>= "
            "180 disables)")(
            "calibration-prior-deg",
            cli::value(registration::MultiViewOptions{}.calibration_prior_rotation_deg, "D"),
            "with known poses, when the joint rounds leave a view past 20 degrees or 0.2 m "
            "from its initial pose (a surface of revolution turning about its axis), they run "
            "again from the initial poses with every view held towards them, as by a rig "
            "calibrated to about D degrees and --calibration-prior-mm; the held result is kept "
            "when fewer views end past the bounds and it matches nearly as many points (0 and "
            "0 = off)")(
            "calibration-prior-mm",
            cli::value(1000.0 * registration::MultiViewOptions{}.calibration_prior_translation_m,
                       "M"),
            "the calibration prior's translation (mm)")(
            "stand", cli::value<std::string>("auto", "MODE"),
            "the stand (turntable platter) below the object, after the alignment: auto "
            "(remove it on streams of 3+ views of one sensor: a turntable), remove, keep; its "
            "plane is written into the views' metadata (rgbd:stand.plane) and rgbd-mesh "
            "carries the object's walls down to it, as rgbd-reconstruct does");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_align); }
