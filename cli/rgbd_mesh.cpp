// rgbd-mesh: surface reconstruction of a view stream.
#include <filesystem>

#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-mesh";
    spec.usage = "rgbd-mesh [options] [FILE...] -o mesh.ply";
    spec.description =
        "Reconstructs a coloured triangle mesh from the views of a stream (merged into one cloud "
        "in the world frame; normals are estimated per view towards its sensor when missing). "
        "--method poisson (default) solves CGAL's Poisson reconstruction on the oriented points "
        "and gives a closed surface; --method advancing-front interpolates the points and keeps "
        "holes open. Vertices are coloured from the nearest measured points. -o FILE picks the "
        "format by extension (.ply binary with vertex colours, .obj, .off); without -o a mesh "
        "document goes to stdout.";
    spec.example =
        "rgbd-cloud cap/ | rgbd-clean | rgbd-align | rgbd-mesh -o bust.ply --metrics mesh.json";
    spec.whole_stream = true;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("method",
                        cli::po::value<std::string>()->default_value("poisson")->value_name("NAME"),
                        "poisson or advancing-front")(
            "max-points", cli::po::value<std::size_t>()->default_value(60000)->value_name("N"),
            "down-sample the input to at most N points first");
    };
    return cli::run_tool(argc, argv, spec, [&](cli::Context& ctx) {
        reconstruction::ReconstructionOptions options;
        try {
            options.method = ctx.get<std::string>("method");
            options.max_points = ctx.get<std::size_t>("max-points");
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
    });
}
