// rgbd-info: a summary of capture folders, view streams, meshes and point files.
#include <CGAL/Polygon_mesh_processing/border.h>

#include <filesystem>
#include <fstream>
#include <iostream>

#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace fs = std::filesystem;

namespace {

Report bbox_of(const std::vector<Eigen::Vector3d>& points) {
    if (points.empty()) return nullptr;
    Eigen::Vector3d lo = points.front(), hi = points.front();
    for (const auto& p : points) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    return {{"min_m", {lo.x(), lo.y(), lo.z()}},
            {"max_m", {hi.x(), hi.y(), hi.z()}},
            {"diagonal_m", (hi - lo).norm()}};
}

Report describe_view(const ViewInfo& v) {
    Report r;
    r["view_id"] = v.id;
    if (!v.sensor.empty()) r["sensor"] = v.sensor;
    if (v.frame_index) r["frame_index"] = *v.frame_index;
    if (v.time_ns) r["time_ns"] = *v.time_ns;
    r["frame"] = v.frame == ViewFrame::kWorld ? "world" : "sensor";
    if (v.has_grid()) r["grid"] = {v.grid_width, v.grid_height};
    if (v.world_from_sensor) {
        const auto t = v.world_from_sensor->translation();
        r["sensor_position_m"] = {t.x(), t.y(), t.z()};
    }
    if (!v.history.empty()) r["history"] = v.history;
    return r;
}

Report describe_cloud(const PointCloud& cloud) {
    Report r = describe_view(cloud.view);
    r["kind"] = "points";
    r["points"] = cloud.size();
    r["normals"] = cloud.points.has_normal_map();
    r["properties"] = cloud.property_names();
    std::vector<Eigen::Vector3d> pts;
    pts.reserve(cloud.size());
    for (auto i : cloud.points) pts.push_back(to_eigen(cloud.points.point(i)));
    r["bbox"] = bbox_of(pts);
    for (const char* flag : {prop::kSynthetic, prop::kNoise}) {
        if (auto map = cloud.flag(flag)) {
            std::size_t n = 0;
            for (auto i : cloud.points) n += (*map)[i] != 0;
            r[std::string(flag) + "_points"] = n;
        }
    }
    return r;
}

Report describe_mesh(const Mesh& mesh) {
    Report r;
    r["kind"] = "mesh";
    r["vertices"] = mesh.number_of_vertices();
    r["faces"] = mesh.number_of_faces();
    std::vector<Mesh::Halfedge_index> border;
    CGAL::Polygon_mesh_processing::border_halfedges(faces(mesh), mesh, std::back_inserter(border));
    r["border_edges"] = border.size();
    r["closed"] = border.empty();
    r["colors"] = vertex_colors(mesh).has_value();
    std::vector<Eigen::Vector3d> pts;
    for (auto v : mesh.vertices()) pts.push_back(to_eigen(mesh.point(v)));
    r["bbox"] = bbox_of(pts);
    return r;
}

Report describe_capture(const std::string& path) {
    const io::Capture capture = io::open_capture(path);
    Report r;
    r["path"] = path;
    r["kind"] = "capture";
    r["layout"] = capture.layout;
    r["framesets"] = capture.framesets.size();
    Report sensors = Report::array();
    for (const auto& s : capture.rig.sensors) {
        const auto it = capture.frames.find(s.id);
        sensors.push_back({{"id", s.id},
                           {"model", s.model},
                           {"depth", {s.depth.width, s.depth.height}},
                           {"color", {s.color.width, s.color.height}},
                           {"frames", it == capture.frames.end() ? 0 : it->second.size()}});
    }
    r["sensors"] = sensors;
    r["ground_truth"] = fs::exists(fs::path(path) / "gt");
    return r;
}

void print_text(std::ostream& os, const Report& r, const std::string& indent = "") {
    for (auto it = r.begin(); it != r.end(); ++it) {
        if (it->is_object()) {
            os << indent << it.key() << ":\n";
            print_text(os, *it, indent + "  ");
        } else if (it->is_array() && !it->empty() && it->front().is_object()) {
            os << indent << it.key() << ":\n";
            for (const auto& e : *it) {
                os << indent << "  -\n";
                print_text(os, e, indent + "    ");
            }
        } else {
            os << indent << it.key() << ": " << it->dump() << "\n";
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
    const cli::ToolSpec spec{.name = "rgbd-info",
                             .usage = "rgbd-info [--json] PATH...",
                             .description =
                                 "Prints a summary of each input: a capture folder (layout, "
                                 "sensors, frames, frame sets, ground truth), a view stream (per "
                                 "document: points, properties, metadata, bounding box, flag "
                                 "counts), a mesh (vertices, faces, border edges, closed, colours) "
                                 "or a point file.",
                             .example = "rgbd-cloud cap/ | rgbd-info --json",
                             .writes_stream = false,
                             .add_options = [](cli::po::options_description& o) {
                                 o.add_options()("json", "print JSON instead of text");
                             }};
    return cli::run_tool(argc, argv, spec, [&](cli::Context& ctx) {
        Report all = Report::array();
        std::vector<std::string> inputs = ctx.inputs();
        if (inputs.empty()) inputs.push_back("-");
        for (const std::string& input : inputs) {
            if (input != "-" && fs::is_directory(input)) {
                all.push_back(describe_capture(input));
                continue;
            }
            const std::string ext = input == "-" ? ".ply" : fs::path(input).extension().string();
            if (input != "-" && !fs::exists(input)) throw IoError(input + ": no such file");
            Report file;
            file["path"] = input;
            if (ext == ".ply" || ext == ".PLY") {
                std::ifstream f;
                std::istream* in = &std::cin;
                if (input != "-") {
                    f.open(input, std::ios::binary);
                    in = &f;
                }
                io::PlyStreamReader reader(*in, input == "-" ? "<stdin>" : input);
                io::Document d;
                Report docs = Report::array();
                while (reader.next(d)) {
                    docs.push_back(d.kind == io::DocumentKind::kMesh ? describe_mesh(d.mesh)
                                                                     : describe_cloud(d.cloud));
                    d = io::Document{};
                }
                if (docs.empty())
                    throw InputError(reader.name() + ": empty stream (no PLY document)");
                file["documents"] = docs;
            } else if (ext == ".off" || ext == ".obj") {
                file["documents"] = Report::array({describe_mesh(io::read_mesh(input))});
            } else {
                file["documents"] = Report::array({describe_cloud(io::read_point_cloud(input))});
            }
            all.push_back(file);
        }
        if (ctx.options().count("json")) {
            ctx.out() << all.dump(2) << "\n";
        } else {
            for (const auto& r : all) {
                print_text(ctx.out(), r);
                ctx.out() << "\n";
            }
        }
    });
}
