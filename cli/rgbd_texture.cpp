// rgbd-texture: a textured model (OBJ + MTL + PNG, or glTF binary) of a mesh from the
// full-resolution colour images of its capture (docs/algorithms.md "Texturing").
#include <cmath>
#include <filesystem>
#include <fstream>

#include "algorithms/texture/texture_mesh.hpp"
#include "cli/common/stages.hpp"
#include "cli/common/tool.hpp"
#include "io/mesh_io.hpp"
#include "io/ply_stream.hpp"
#include "io/textured_mesh_io.hpp"
#include "pipeline/texture_views.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

/// The point views of a stream file (the aligned views of rgbd-align); mesh documents skipped.
std::vector<PointCloud> read_views(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    RGBD_CHECK_AS(IoError, in.good(), path + ": cannot open");
    io::PlyStreamReader reader(in, path);
    std::vector<PointCloud> views;
    io::Document doc;
    while (reader.next(doc))
        if (doc.kind == io::DocumentKind::kPoints) {
            PointCloud header;
            header.view = doc.cloud.view;  // the poses are all that is needed
            views.push_back(std::move(header));
        }
    RGBD_CHECK(!views.empty(), path + ": no views in the stream");
    return views;
}

void run_texture(cli::Context& ctx) {
    if (ctx.inputs().size() != 1) throw cli::UsageError("expected exactly one MESH file");
    if (ctx.output_path().empty()) throw cli::UsageError("give the model file with -o MODEL");
    if (!io::is_textured_format(ctx.output_path()))
        throw cli::UsageError("-o: the model is written as .obj (+ .mtl + .png) or .glb, not " +
                              ctx.output_path());
    if (!ctx.options().count("capture")) throw cli::UsageError("give the capture with --capture");
    texture::TextureOptions options;
    try {
        options.selection.smoothness = ctx.get<double>("smoothness");
        options.selection.sweeps = ctx.get<int>("sweeps");
        options.selection.min_cos = std::cos(ctx.get<double>("max-angle-deg") * M_PI / 180.0);
        options.selection.sharpness = !ctx.options().count("no-sharpness");
        options.adjust.enabled = !ctx.options().count("no-adjust");
        options.consistency.enabled = !ctx.options().count("no-consistency");
        options.consistency.max_levels = ctx.get<double>("consistency-levels");
        options.levelling.enabled = !ctx.options().count("no-levelling");
        options.levelling.smoothness = ctx.get<double>("levelling-smoothness");
        options.atlas.max_size = ctx.get<int>("max-atlas");
        options.atlas.scale = ctx.get<double>("texel-scale");
        options.atlas.min_scale = std::min(options.atlas.min_scale, options.atlas.scale);
        options.atlas.padding_px = ctx.get<int>("padding");
        options.refine.enabled = ctx.options().count("refine-colour") > 0;
        options.refine.iterations = ctx.get<int>("refine-colour-iterations");
        options.check();
    } catch (const InputError& e) {
        throw cli::UsageError(e.what());
    }
    const std::string mesh_path = ctx.inputs().front();
    const Mesh mesh = io::read_mesh(mesh_path);
    if (mesh.number_of_faces() == 0) throw InputError(mesh_path + ": the mesh has no faces");
    const io::Capture capture = io::open_capture(ctx.get<std::string>("capture"));
    std::vector<PointCloud> aligned;
    std::vector<std::pair<std::string, std::size_t>> frames;
    if (ctx.options().count("views")) {
        aligned = read_views(ctx.get<std::string>("views"));
        frames = pipeline::frames_of_views(capture, aligned);
    } else {
        frames = cli::select_frames(
            capture, ctx.get<long long>("frameset"),
            ctx.options().count("frames") ? ctx.get<std::string>("frames") : std::string(), {},
            &ctx);
    }
    Stopwatch watch;
    const auto views =
        pipeline::load_texture_views(capture, frames, aligned.empty() ? nullptr : &aligned);
    Report report;
    report["load_s"] = watch.seconds();
    TexturedMesh model;
    {
        auto bar = ctx.progress("texture");
        try {
            model = texture::texture_mesh(mesh, views, options, report, bar.callback());
        } catch (const InputError& e) {
            throw InputError(mesh_path + ": " + e.what());
        }
    }
    cli::warn_refused_colour_poses(ctx, report);
    const std::size_t unseen = report["selection"]["unseen_faces"].get<std::size_t>();
    if (report["atlas"]["texel_scale"].get<double>() < options.atlas.scale)
        ctx.warn(
            cli::formatted("the charts did not fit into %d x %d texels: texel size scaled "
                           "by %.3f",
                           options.atlas.max_size, options.atlas.max_size,
                           report["atlas"]["texel_scale"].get<double>()));
    if (report["atlas"]["atlases"].get<int>() > 1)
        ctx.warn("the texture is split into " + report["atlas"]["atlases"].dump() + " atlases");
    Stopwatch write_watch;
    io::write_textured_mesh(ctx.output_path(), model,
                            std::string(cli::kVersion).insert(0, "rgbd-texture "));
    report["write_s"] = write_watch.seconds();
    report["files"] = Report::array();
    for (const auto& f : io::textured_mesh_files(ctx.output_path(), model))
        report["files"].push_back(f.string());
    ctx.metrics()["texture"] = report;
    ctx.note(cli::formatted(
        "%s: %zu faces, %zu charts, %d atlas(es) %s, %zu faces no camera "
        "sees (flat colour)",
        ctx.output_path().c_str(), model.faces.size(), report["atlas"]["charts"].get<std::size_t>(),
        report["atlas"]["atlases"].get<int>(), report["atlas"]["atlas_sizes"].dump().c_str(),
        unseen));
}

const texture::TextureOptions kDefaults{};

const cli::ToolSpec kSpec{
    .name = "rgbd-texture",
    .usage = "rgbd-texture MESH --capture CAPTURE_DIR [--views ALIGNED.ply] -o MODEL.obj|MODEL.glb",
    .description =
        "Textures a mesh (world frame, as rgbd-mesh or rgbd-reconstruct write it) from the "
        "full-resolution colour images of its capture. Each face takes the colour camera that "
        "sees it best (projected area x cosine of the viewing angle x image sharpness; "
        "visibility by a depth test against the mesh rendered into every colour camera), traded "
        "against a smoothness term over face adjacency (iterated conditional modes) so that "
        "charts are large; per-camera gains and offsets, fitted where cameras overlap, level "
        "the colours; a camera whose colour of a face lies far from the median of the cameras "
        "seeing it loses that face (occluders, moving parts, highlights); additive per-vertex "
        "corrections, solved by least squares, remove the remaining steps across the seams "
        "between charts; each chart's rectangle of its image is packed into power-of-two atlases "
        "(at most --max-atlas texels a side: the texel size is scaled down, or more atlases are "
        "written, with a warning). Faces no camera sees get the mesh's vertex colours as flat "
        "colours (counted in the metrics). Poses: the capture's (rig.json, frames.csv), or the "
        "refined per-view poses of the aligned views with --views (rgbd-align's output), which "
        "also selects the frames. -o MODEL.obj writes MODEL.obj, MODEL.mtl and MODEL.png "
        "(MODEL_N.png for several atlases); -o MODEL.glb one glTF 2.0 binary with the texture "
        "embedded. All files appear whole or not at all. --refine-colour first refines each "
        "colour camera's pose against the mesh by photometric consistency (depth-to-colour "
        "extrinsics slightly off; Zhou and Koltun 2014, rigid part); corrections above 3 degrees "
        "or 30 mm are refused with a warning; the metrics list each camera's correction and the "
        "residual before and after.",
    .example =
        "rgbd-cloud cap/ | rgbd-clean | rgbd-align > aligned.ply; rgbd-mesh aligned.ply "
        "--watertight -o bust.ply; rgbd-texture bust.ply --capture cap/ --views "
        "aligned.ply -o bust.obj",
    .writes_stream = false,
    .reads_stream = false,
    .writes_file = true,
    .ranges = {{"smoothness", Range::closed(0, 100)},
               {"sweeps", Range::closed(0, 1000)},
               {"max-angle-deg", Range::closed(1, 89), "degrees"},
               {"max-atlas", Range::closed(64, 16384), "texels"},
               {"texel-scale", Range::open_closed(0, 1)},
               {"consistency-levels", Range::open_closed(0, 442), "levels"},
               {"levelling-smoothness", Range::open_closed(0, 1e6)},
               {"padding", Range::closed(1, 64), "px"},
               {"refine-colour-iterations", Range::closed(1, 1000)}},
    .scopes = {{{"refine-colour"}, {"refine-colour-iterations"}}},
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("capture", cli::value<std::string>("DIR"),
                        "capture folder with the colour images (required)")(
            "views", cli::value<std::string>("ALIGNED.ply"),
            "aligned views (rgbd-align's output): their refined poses and frames")(
            "frameset", cli::value<long long>(0, "N"),
            "frame set whose colour images texture the mesh (without --views)")(
            "frames", cli::value<std::string>("A:B[:STEP]"),
            "frame positions (single-sensor sequences, without --views; default all)")(
            "smoothness", cli::value(kDefaults.selection.smoothness, "W"),
            "weight of the smoothness term (0 = best view per face)")(
            "sweeps", cli::value(kDefaults.selection.sweeps, "N"), "ICM sweeps")(
            "max-angle-deg",
            // The library's angle itself (so that rgbd-reconstruct -o .obj, which calls the
            // library, textures alike), shown to 0.01 degree.
            cli::value<double>("D")->default_value(
                std::acos(kDefaults.selection.min_cos) * 180.0 / M_PI,
                cli::formatted("%.2f", std::acos(kDefaults.selection.min_cos) * 180.0 / M_PI)),
            "faces seen more obliquely than this are not textured from that camera")(
            "no-sharpness", "leave the image sharpness out of the view quality")(
            "no-adjust", "no per-camera colour adjustment")(
            "no-consistency", "keep cameras whose colour of a face disagrees with the others")(
            "consistency-levels", cli::value(kDefaults.consistency.max_levels, "L"),
            "a camera loses a face when its colour lies farther than this from the median "
            "colour of the cameras seeing it (levels)")("no-levelling", "no local seam levelling")(
            "levelling-smoothness", cli::value(kDefaults.levelling.smoothness, "W"),
            "weight of the smoothness of the seam corrections inside a chart")(
            "max-atlas", cli::value(kDefaults.atlas.max_size, "N"),
            "largest atlas side in texels (a power of two)")(
            "texel-scale", cli::value(kDefaults.atlas.scale, "F"),
            "texels per colour-image pixel (<= 1)")(
            "refine-colour",
            "refine the colour cameras' poses against the mesh (photometric consistency) first")(
            "refine-colour-iterations", cli::value(kDefaults.refine.iterations, "N"),
            "most Gauss-Newton iterations per pyramid level of --refine-colour")(
            "padding", cli::value(kDefaults.atlas.padding_px, "PX"),
            "image pixels kept around each chart");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_texture); }
