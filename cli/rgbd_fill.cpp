// rgbd-fill: hole detection, small-hole filling, large holes and the head top on aligned views
// (docs/algorithms.md §9-§13).
#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

void run_fill(cli::Context& ctx) {
    const auto& vm = ctx.options();
    holes::BoundaryOptions detect;
    holes::FillOptions fill;
    holes::InpaintOptions inpaint;
    try {
        detect.neighbourhood.k = ctx.get<int>("k");
        detect.neighbourhood.radius_factor = ctx.get<double>("radius-factor");
        if (vm.count("spacing-m")) {
            detect.spacing_m = ctx.get<double>("spacing-m");
            if (!(detect.spacing_m > 0))
                throw cli::UsageError("--spacing-m must be a positive number");
        }
        detect.threshold = ctx.get<double>("threshold");
        const auto w = cli::parse_doubles(ctx.get<std::string>("weights"), "--weights");
        if (w.size() != 3) throw cli::UsageError("--weights needs three numbers A,H,S");
        detect.w_angle = w[0];
        detect.w_halfdisk = w[1];
        detect.w_shape = w[2];
        detect.coherence_passes = ctx.get<int>("coherence");
        detect.coherence_both = vm.count("coherence-both") > 0;
        detect.hysteresis_threshold = ctx.get<double>("hysteresis");
        detect.hysteresis_rings = ctx.get<int>("hysteresis-rings");
        detect.min_loop_points = ctx.get<int>("min-loop");
        detect.small_max_diameter = ctx.get<double>("small-diameter");
        detect.small_max_points = ctx.get<int>("small-points");
        detect.visible_max_angle_deg = ctx.get<double>("visible-angle-deg");
        detect.check();
        fill.mechanism = holes::parse_fill_mechanism(ctx.get<std::string>("mechanism"));
        fill.step = ctx.get<double>("step");
        fill.max_sweeps = ctx.get<int>("max-sweeps");
        fill.max_fit_rms = ctx.get<double>("max-fit-rms");
        fill.fill_openings = vm.count("fill-openings") > 0;
        fill.check();
        inpaint.pixel = ctx.get<double>("inpaint-pixel");
        inpaint.telea_radius = ctx.get<double>("telea-radius");
        const std::string colour = ctx.get<std::string>("colour-inpaint");
        if (colour == "criminisi")
            inpaint.colour = holes::ColourInpaint::kCriminisi;
        else if (colour == "telea")
            inpaint.colour = holes::ColourInpaint::kTelea;
        else
            throw cli::UsageError("--colour-inpaint must be criminisi or telea, not '" + colour +
                                  "'");
        inpaint.patch = ctx.get<int>("patch");
        inpaint.search_window = ctx.get<double>("search-window");
        inpaint.top_fraction = ctx.get<double>("top-fraction");
        inpaint.top_min_up = ctx.get<double>("top-min-up");
        inpaint.top_fit_radii = ctx.get<double>("top-fit-radii");
        inpaint.ellipsoid = vm.count("no-ellipsoid") == 0;
        inpaint.max_ellipsoid_rms = ctx.get<double>("max-ellipsoid-rms");
        inpaint.biharmonic = vm.count("no-biharmonic") == 0;
        inpaint.max_biharmonic_slope = ctx.get<double>("max-biharmonic-slope");
        inpaint.max_open_rim = ctx.get<double>("max-open-rim");
        inpaint.top_without_ellipsoid = vm.count("top-without-ellipsoid") > 0;
        inpaint.min_rim_radial = ctx.get<double>("min-rim-radial");
        inpaint.clearance = ctx.get<double>("clearance");
        inpaint.carve = vm.count("no-carve") == 0;
        inpaint.free_space.margin = ctx.get<double>("carve-margin");
        inpaint.max_contradicted = ctx.get<double>("max-contradicted");
        inpaint.visible_max_angle_deg = detect.visible_max_angle_deg;
        inpaint.fill_openings = fill.fill_openings;
        inpaint.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    cli::FillStageOptions stage;
    stage.detect = detect;
    stage.fill = fill;
    stage.inpaint = inpaint;
    stage.detect_only = vm.count("detect-only") > 0;
    stage.mark = vm.count("mark") > 0;
    stage.large = vm.count("no-large") == 0;
    stage.head_top = vm.count("no-head-top") == 0;
    stage.ignore_poses = vm.count("ignore-poses") > 0;
    stage.debug_colors = vm.count("debug-colors") > 0;
    const int max_points = ctx.get<int>("max-points");
    if (max_points < 0) throw cli::UsageError("--max-points must be 0 or more");
    stage.max_points = static_cast<std::size_t>(max_points);

    std::vector<io::Document> documents = ctx.read_all_documents();
    std::vector<PointCloud*> views;
    for (std::size_t d = 0; d < documents.size(); ++d) {
        if (documents[d].kind != io::DocumentKind::kPoints) {
            ctx.warn("document " + std::to_string(d) + " is a mesh; passed through");
            continue;
        }
        views.push_back(&documents[d].cloud);
    }
    Report report;
    std::optional<PointCloud> added;
    {
        auto bar = ctx.progress("fill");
        added = cli::fill_stage(views, stage, report, bar.callback());
    }
    if (report.contains("note")) ctx.warn(report["note"].get<std::string>());
    if (report.contains("loop_list")) {
        ctx.add_document_metrics(report);
        ctx.info("fill: " + report.dump());
        ctx.note(std::to_string(report["loop_list"].size()) + " hole loops (" +
                 std::to_string(report.value("small_loops", std::size_t{0})) + " small), " +
                 std::to_string(report["points_added_total"].get<std::size_t>()) + " points added");
    }
    for (auto& document : documents) ctx.write(document);
    if (!added) return;
    io::Document filled;
    filled.kind = io::DocumentKind::kPoints;
    filled.cloud = std::move(*added);
    // The new view's id follows every document's, meshes included.
    for (const auto& document : documents)
        filled.cloud.view.id = std::max(filled.cloud.view.id, document.cloud.view.id + 1);
    ctx.write(filled);
}

const cli::ToolSpec kSpec{
    .name = "rgbd-fill",
    .usage =
        "rgbd-fill [--mechanism NAME] [--detect-only] [--mark] [options] [FILE...] > "
        "filled.ply",
    .description =
        "Finds holes in the surface sampled by a stream of aligned views and fills the small "
        "ones (docs/algorithms.md §9-§11); reads the whole stream. All views are taken "
        "together in the world frame (sensor-frame views are moved with their pose). Per "
        "point: normal and tangent frame (the views' normals, else PCA over the neighbours), "
        "then the boundary probability of Bendels et al. combining the angle criterion "
        "(largest angular gap between the neighbours projected on the tangent plane), the "
        "half-disk criterion (offset of the neighbourhood's centroid) and the shape criterion "
        "(eigenvalues of the neighbourhood), over a symmetric kNN-or-radius neighbourhood; a "
        "candidate must be coherent (a neighbour bounding its gap is a candidate too; both "
        "with --coherence-both), and rims grow one ring into neighbours above --hysteresis. "
        "Connected rims of boundary points are loops, small when their diameter is at most "
        "--small-diameter spacings. The views' sensor poses tell an occlusion hole (no sensor "
        "had a clear, front-facing line of sight to it: fill it) from a real opening (a sensor "
        "looked through it and measured nothing, like the gap between an arm and the body: "
        "left open unless --fill-openings). Small occlusion holes are filled by one of the "
        "four mechanisms of §11: 'one' point at the largest angle of each rim point, 'four' "
        "points at its four largest angles, 'three' points splitting its largest angle (all "
        "swept until the hole closes), or 'interpolation' (default, the best measured: a "
        "quadric fitted around the hole, lifted hexagonal grid at the point spacing; a hole "
        "whose surroundings the quadric does not fit within --max-fit-rms spacings, a crease "
        "or two layers, stays open). New points lie on a quadric fitted to the measured "
        "points, never outside the rim, and get an interpolated colour. Output: the input "
        "documents unchanged (with --mark, each point gets the properties boundary = 0/1 and "
        "boundary_probability), then one new world-frame document with the added points "
        "(sensor 'rgbd-fill', synthetic = 1, fill_mechanism = 1-4, normals, colours). "
        "--detect-only writes no new document. Then the head top (§13, --no-head-top to skip): "
        "the crown that a level ring of sensors never sees, as a top-down height map of the "
        "top --top-fraction of the height along the body's vertical axis (the normal of the "
        "plane through the sensor centres, else the cloud's principal axis); its hole (unknown "
        "pixels inside the hull of the known ones) gets the height of an ellipsoid fitted to "
        "the top points plus the rim's residual to it carried into the hole by a harmonic "
        "solve (the ellipsoid's shape, the rim's place); a top the ellipsoid does not fit "
        "within --max-ellipsoid-rms (a wreath, a hat) stays open unless "
        "--top-without-ellipsoid. Then large holes (§12, --no-large to skip): the surface "
        "unwrapped on a cylinder around the axis (radius and colour over angle x height, "
        "pixels of --inpaint-pixel spacings), hole = unknown pixels between the lowest and "
        "highest known pixel of their column (the bottom cut stays open), inpainted by Telea "
        "(OpenCV) and a biharmonic solve, 3x3 median, back to 3D at the point spacing; a hole "
        "whose rim does not face away from the axis (the surface is not star-shaped there: "
        "under the chin, arms) or that a sensor looked through is left open. The colour of "
        "both (§12.2) is inpainted by Criminisi's exemplar-based method (--colour-inpaint "
        "criminisi, default: --patch x --patch patches copied in order of confidence x "
        "isophote strength, best CIELab match within --search-window x the hole's box; texture "
        "stays texture) or by Telea (--colour-inpaint telea: smooth, blurs texture). Added "
        "points keep --clearance spacings from every other point. fill_mechanism: 1-4 small "
        "holes, 5 large holes, 6 head top.",
    .example =
        "rgbd-cloud cap/ | rgbd-clean | rgbd-align | rgbd-clean --density | rgbd-fill | "
        "rgbd-mesh -o bust.ply",
    .reads_cloud_files = true,
    .whole_stream = true,
    .ranges = {{"spacing-m", Range::open_closed(0, 10), "m"},
               {"max-ellipsoid-rms", Range::open_closed(0, 1000), "spacings"},
               {"max-biharmonic-slope", Range::closed(0, 1000)},
               {"max-fit-rms", Range::open_closed(0, 1000), "spacings"}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("mechanism", cli::value<std::string>("interpolation", "NAME"),
                        "small-hole filling: one, four, three or interpolation (§11 M1-M4)")(
            "detect-only", "detect holes, add no points")(
            "mark",
            "add the properties boundary (0/1) and boundary_probability to every input point")(
            "debug-colors",
            "colour added points by mechanism (M1 red, M2 green, M3 blue, M4 yellow, large "
            "holes magenta, head top cyan) instead of the interpolated colour")(
            "max-points", cli::value(static_cast<int>(cli::FillStageOptions{}.max_points), "N"),
            "more measured points than N (a merged sequence of many frames) are thinned to "
            "about N, one measured point per voxel, before detection and inpainting; 0 = "
            "never (--mark never thins)")("no-large", "do not fill large holes (§12)")(
            "no-head-top", "do not fill the head top (§13)")(
            "inpaint-pixel", cli::value(holes::InpaintOptions{}.pixel, "X"),
            "pixel size of the inpainting images, in spacings")(
            "telea-radius", cli::value(holes::InpaintOptions{}.telea_radius, "PX"),
            "neighbourhood radius of Telea's inpainting, pixels")(
            "colour-inpaint", cli::value<std::string>("criminisi", "NAME"),
            "colour of large holes and the head top: criminisi (exemplar-based) or telea")(
            "patch", cli::value(holes::InpaintOptions{}.patch, "PX"),
            "Criminisi's patch side, pixels (odd)")(
            "search-window", cli::value(holes::InpaintOptions{}.search_window, "X"),
            "Criminisi's search window, X times the hole's bounding box")(
            "top-fraction", cli::value(holes::InpaintOptions{}.top_fraction, "F"),
            "head top: the top F of the height along the vertical axis")(
            "top-min-up", cli::value(holes::InpaintOptions{}.top_min_up, "C"),
            "head top: a height-map column is known only if its highest point's outward normal "
            "has a component along the vertical axis of at least C (a chin seen from below is "
            "not the crown; a little below 0: a wall seen edge-on is; -1: every column)")(
            "top-fit-radii", cli::value(holes::InpaintOptions{}.top_fit_radii, "K"),
            "head top: fit the ellipsoid to the top points at most K hole radii below the "
            "highest (0: every top point)")("no-ellipsoid",
                                            "head top: no ellipsoid fit (inpainted heights only)")(
            "max-ellipsoid-rms", cli::value(holes::InpaintOptions{}.max_ellipsoid_rms, "X"),
            "head top: use the ellipsoid only when it fits the top points within X spacings "
            "RMS")("top-without-ellipsoid",
                   "head top: fill with the inpainted heights when the ellipsoid does not fit "
                   "(else the crown stays open)")(
            "no-biharmonic", "geometry by Telea only (no biharmonic solve in the holes)")(
            "max-open-rim", cli::value(holes::InpaintOptions{}.max_open_rim, "F"),
            "large holes: fill only holes whose edge borders the outside of the surface (below "
            "its lowest or above its highest point in a column) for at most the share F")(
            "max-biharmonic-slope", cli::value(holes::InpaintOptions{}.max_biharmonic_slope, "S"),
            "large holes: harmonic instead of biharmonic solve where the radius changes faster "
            "than S times the height (the underside of an overhang)")(
            "min-rim-radial", cli::value(holes::InpaintOptions{}.min_rim_radial, "C"),
            "large holes: fill only when the rim normals' mean n.radial is at least C")(
            "clearance", cli::value(holes::InpaintOptions{}.clearance, "X"),
            "large holes and head top: no new point within X spacings of another")(
            "no-carve",
            "large holes and head top: keep new points that a sensor saw as empty space")(
            "carve-margin", cli::value(holes::InpaintOptions{}.free_space.margin, "X"),
            "large holes and head top: a new point is in empty space when a sensor facing it "
            "measured the surface more than X spacings behind it (or nothing)")(
            "max-contradicted", cli::value(holes::InpaintOptions{}.max_contradicted, "F"),
            "large holes and head top: a hole whose new points the sensors contradict in more "
            "than the share F stays open")("fill-openings",
                                           "also fill small holes that a sensor saw through")(
            "ignore-poses", "no visibility test: every small hole is filled")(
            "k", cli::value(holes::BoundaryOptions{}.neighbourhood.k, "N"),
            "nearest neighbours of the boundary criteria")(
            "radius-factor", cli::value(holes::BoundaryOptions{}.neighbourhood.radius_factor, "X"),
            "radius neighbours within X spacings join the nearest ones")(
            "spacing-m", cli::value<double>("M"),
            "point spacing in metres (default: the robust spacing of the points)")(
            "threshold", cli::value(holes::BoundaryOptions{}.threshold, "P"),
            "boundary when the combined probability is at least P")(
            "weights", cli::value<std::string>("0.4,0.4,0.2", "A,H,S"),
            "weights of the angle, half-disk and shape criteria")(
            "coherence", cli::value(holes::BoundaryOptions{}.coherence_passes, "N"),
            "coherence passes (0 = off): a candidate needs a candidate among the two "
            "neighbours bounding its largest gap")(
            "coherence-both", "coherence needs both gap neighbours to be candidates")(
            "hysteresis", cli::value(holes::BoundaryOptions{}.hysteresis_threshold, "P"),
            "rims grow into neighbours with a probability of at least P (0 = off)")(
            "hysteresis-rings", cli::value(holes::BoundaryOptions{}.hysteresis_rings, "N"),
            "rings of neighbours the rims grow at most")(
            "min-loop", cli::value(holes::BoundaryOptions{}.min_loop_points, "N"),
            "rims with fewer boundary points are noise")(
            "small-diameter", cli::value(holes::BoundaryOptions{}.small_max_diameter, "X"),
            "small hole: rim diameter at most X spacings")(
            "small-points", cli::value(holes::BoundaryOptions{}.small_max_points, "N"),
            "small hole: at most N rim points")(
            "visible-angle-deg", cli::value(holes::BoundaryOptions{}.visible_max_angle_deg, "DEG"),
            "a sensor sees a hole region facing it within DEG")(
            "step", cli::value(holes::FillOptions{}.step, "X"),
            "distance of new points, in spacings")(
            "max-sweeps", cli::value(holes::FillOptions{}.max_sweeps, "N"),
            "sweeps over the rim at most (one, four, three)")(
            "max-fit-rms", cli::value(holes::FillOptions{}.max_fit_rms, "X"),
            "interpolation: fill a hole only when the quadric fits the points around it within "
            "X spacings RMS (else it is a crease, not a hole on a smooth sheet)");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_fill); }
