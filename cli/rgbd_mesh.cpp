// rgbd-mesh: surface reconstruction of a view stream.
#include <filesystem>

#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

void run_mesh(cli::Context& ctx) {
    reconstruction::ReconstructionOptions options;
    try {
        options.method = ctx.get<std::string>("method");
        // Read signed, so that a negative count is named as given, not as its wrap-around.
        const long long max_points = ctx.get<long long>("max-points");
        const long long target_faces = ctx.get<long long>("target-faces");
        if (max_points < 0)
            throw cli::UsageError("--max-points must be >= 0, got " + std::to_string(max_points));
        if (target_faces < 0)
            throw cli::UsageError("--target-faces must be 0 (keep) or >= 4, got " +
                                  std::to_string(target_faces));
        options.max_points = static_cast<std::size_t>(max_points);
        options.watertight = ctx.options().count("watertight") > 0;
        if (ctx.options().count("no-carve-closure")) options.carve_steps = 0;
        options.repair_self_intersections = ctx.options().count("repair-self-intersections") > 0;
        options.target_faces = static_cast<std::size_t>(target_faces);
        options.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    std::vector<PointCloud> views = cli::read_point_views(ctx);
    auto bar = ctx.progress("mesh");
    Report report;
    ViewInfo info;
    info.frame = ViewFrame::kWorld;
    info.sensor = "mesh";
    for (const auto& v : views)
        for (const auto& h : v.view.history)
            if (std::find(info.history.begin(), info.history.end(), h) == info.history.end())
                info.history.push_back(h);
    // A stand removed by rgbd-align: the object's walls carried down to its plane.
    const std::size_t contact = pipeline::add_stand_contact(views);
    if (contact > 0) report["stand_contact_points"] = contact;
    Mesh mesh = cli::mesh_stage(std::move(views), options, report, bar.callback());
    ctx.add_history(info);
    ctx.metrics()["mesh"] = report;
    ctx.info("mesh: " + std::to_string(mesh.number_of_vertices()) + " vertices, " +
             std::to_string(mesh.number_of_faces()) + " faces");
    if (!ctx.output_path().empty()) {
        io::write_mesh(ctx.output_path(), mesh, &info);
    } else {
        io::write_mesh(ctx.out(), mesh, info);
    }
}

const cli::ToolSpec kSpec{
    .name = "rgbd-mesh",
    .usage = "rgbd-mesh [options] [FILE...] -o mesh.ply",
    .description =
        "Reconstructs a coloured triangle mesh from the views of a stream (merged into one "
        "cloud in the world frame; normals are estimated per view towards its sensor when "
        "missing). --method front (default) denoises the oriented points by a normal-aware "
        "moving-least-squares projection (the two sides of thin parts stay apart), thins them "
        "to the point spacing and interpolates them by CGAL's advancing front restricted to "
        "short triangles whose corners' normals agree: detail and thin parts survive and no "
        "surface is invented where no sensor looked, so unseen regions stay open. --watertight "
        "closes every remaining hole into a closed 2-manifold: the loop at the bottom of the "
        "object (up from the sensors' poses) is the cut it stood on and gets straight sides "
        "down to a flat base (on the ground the extraction found, when the cut reaches it: "
        "there the sides are carved inward where the sensors saw the floor through them, "
        "read again from each view's source frame, rgbd:view.source); every other hole is "
        "triangulated, refined and faired; patches "
        "that fold onto themselves are repaired (--repair-self-intersections repairs every "
        "face crossing another). --method "
        "poisson solves CGAL's (unscreened) Poisson reconstruction and gives a closed surface; "
        "--method advancing-front interpolates the raw points. Components smaller than 1% of "
        "the largest are dropped. --target-faces N simplifies by edge collapse "
        "(Garland-Heckbert quadrics). Vertices are coloured from the nearest measured points. "
        "-o FILE picks the format by extension (.ply binary with vertex colours, .obj, .off); "
        "without -o a mesh document goes to stdout.",
    .example =
        "rgbd-cloud cap/ | rgbd-clean | rgbd-align | rgbd-mesh -o bust.ply --metrics mesh.json",
    .whole_stream = true,
    .scopes = {{{"watertight"}, {"no-carve-closure"}}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("method",
                        cli::value(reconstruction::ReconstructionOptions{}.method, "NAME"),
                        "front, poisson or advancing-front")(
            "watertight", "close every hole: the result is a closed 2-manifold")(
            "no-carve-closure",
            "--watertight: keep the faired hole patches and a ground base's sides as they are "
            "(default: carved back out of the space at least two sensors saw empty)")(
            "repair-self-intersections",
            "remove the faces that cross others and refill their holes, last (a closed mesh "
            "then bounds a volume; see the report's self_intersections)")(
            "target-faces",
            cli::value(static_cast<long long>(reconstruction::ReconstructionOptions{}.target_faces),
                       "N"),
            "simplify to at most N faces (0 = no simplification)")(
            "max-points",
            cli::value(static_cast<long long>(reconstruction::ReconstructionOptions{}.max_points),
                       "N"),
            "down-sample the input to at most N points first");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_mesh); }
