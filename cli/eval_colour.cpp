#include "cli/eval_colour.hpp"

#include <filesystem>
#include <fstream>

#include "algorithms/texture/surface_colour.hpp"
#include "io/capture_folder.hpp"
#include "io/ply_stream.hpp"
#include "io/textured_mesh_io.hpp"
#include "pipeline/texture_views.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli {
namespace fs = std::filesystem;

LoadedResult load_eval_input(const std::string& path) {
    if (fs::path(path).extension() != ".glb") return load_result(path);
    const TexturedMesh model = io::read_textured_mesh(path);
    LoadedResult out;
    Mesh mesh;
    std::vector<Mesh::Vertex_index> ids;
    for (const auto& p : model.vertices)
        ids.push_back(mesh.add_vertex(Point_3(p.x(), p.y(), p.z())));
    for (const auto& f : model.faces) mesh.add_face(ids[f[0]], ids[f[1]], ids[f[2]]);
    if (!model.vertex_colors.empty()) {
        auto colours = add_vertex_colors(mesh);
        for (std::size_t i = 0; i < ids.size(); ++i) {
            const Rgb& c = model.vertex_colors[i];
            colours[ids[i]] = MeshColor(c.r, c.g, c.b);
        }
    }
    out.mesh = std::move(mesh);
    return out;
}

Report colour_report(Context& ctx, const std::string& model_path) {
    const std::string root = ctx.get<std::string>("colour");
    const io::Capture capture = io::open_capture(root);
    std::vector<PointCloud> aligned;
    std::vector<std::pair<std::string, std::size_t>> frames;
    std::string poses = "capture";
    if (ctx.options().count("colour-views")) {
        const std::string path = ctx.get<std::string>("colour-views");
        std::ifstream in(path, std::ios::binary);
        RGBD_CHECK_AS(IoError, in.good(), path + ": cannot open");
        io::PlyStreamReader reader(in, path);
        io::Document doc;
        while (reader.next(doc))
            if (doc.kind == io::DocumentKind::kPoints) {
                PointCloud header;
                header.view = doc.cloud.view;
                aligned.push_back(std::move(header));
            }
        frames = pipeline::frames_of_views(capture, aligned);
        poses = "views";
    } else {
        frames = select_frames(
            capture, ctx.get<long long>("frameset"),
            ctx.options().count("frames") ? ctx.get<std::string>("frames") : std::string(), {},
            &ctx);
        // The truth as poses of views (sensor-level poses of a rig capture).
        for (const auto& [id, pose] : pipeline::read_sensor_gt_poses(capture)) {
            PointCloud header;
            header.view.sensor = id;
            header.view.world_from_sensor = pose;
            aligned.push_back(std::move(header));
        }
        if (!aligned.empty()) poses = "gt";
    }
    const auto views =
        pipeline::load_texture_views(capture, frames, aligned.empty() ? nullptr : &aligned);
    const TexturedMesh model = io::read_textured_mesh(model_path);
    texture::ColourError error;
    try {
        error = texture::surface_colour_error(model, views);
    } catch (const InputError& e) {
        throw InputError(model_path + ": " + e.what());
    }
    Report report = error.report;
    report["capture"] = root;
    report["poses"] = poses;
    ctx.note(
        formatted("colour against %s (%zu images, %s poses): PSNR %.2f dB, mean absolute "
                  "error %.2f levels (%s, %zu pixels)",
                  root.c_str(), views.size(), poses.c_str(), error.psnr_db, error.mae,
                  report["source"].get<std::string>().c_str(), error.pixels));
    return report;
}

}  // namespace rgbd::cli
