// rgbd-info: a summary of capture folders, view streams, meshes and point files.
#include <CGAL/Polygon_mesh_processing/border.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "cli/common/tool.hpp"
#include "io/capture_folder.hpp"
#include "io/mesh_io.hpp"
#include "io/video.hpp"
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
        std::size_t posed = 0;
        if (it != capture.frames.end())
            for (const io::FrameRecord& f : it->second) posed += f.world_from_depth.has_value();
        Report sensor = {{"id", s.id},
                         {"model", s.model},
                         {"depth", {s.depth.width, s.depth.height}},
                         {"color", {s.color.width, s.color.height}},
                         {"frames", it == capture.frames.end() ? 0 : it->second.size()},
                         {"frames_with_pose", posed}};
        if (!s.noise_model.empty()) sensor["noise_model"] = s.noise_model;
        if (s.depth_encoding != io::DepthEncoding::kPlain)
            sensor["depth_encoding"] = io::to_string(s.depth_encoding);
        if (s.range_max_m > 0) sensor["range_m"] = {s.range_min_m, s.range_max_m};
        sensors.push_back(sensor);
    }
    r["sensors"] = sensors;
    r["ground_truth"] = fs::exists(fs::path(path) / "gt");
    return r;
}

double quantile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

/// A 3D video folder (io/video.hpp): frames, timing, sizes, and every frame that cannot be
/// played, named with its problem.
Report describe_video(const std::string& path, cli::Context& ctx) {
    const io::VideoInfo video = io::read_video(path);
    Report r;
    r["path"] = path;
    r["kind"] = "video";
    for (const char* key : {"placement", "voxel_m", "frame_rate_hz", "stop_reason"})
        if (video.header.contains(key)) r[key] = video.header[key];
    r["complete"] = video.complete;
    if (video.header.contains("rig") && video.header["rig"].contains("sensors"))
        r["sensors"] = video.header["rig"]["sensors"].size();
    std::vector<double> points, bytes, hub, latency, spread;
    Report problems = Report::array();
    std::size_t unindexed = 0, thinned = 0;
    const int rig_sensors = r.value("sensors", 0);
    for (const io::VideoFrame& f : video.frames) {
        unindexed += !f.indexed;
        if (!f.problem.empty()) {
            problems.push_back({{"frame", f.frame}, {"file", f.file}, {"problem", f.problem}});
            ctx.warn(path + "/" + f.file + ": " + f.problem + " (skipped when played)");
            continue;
        }
        points.push_back(static_cast<double>(f.points));
        bytes.push_back(static_cast<double>(f.bytes));
        if (f.indexed) {
            hub.push_back(f.hub_ms);
            latency.push_back(f.latency_ms);
            spread.push_back(1e-6 * static_cast<double>(f.spread_ns));
            thinned += f.sensors < rig_sensors;
        }
    }
    r["frames"] = video.frames.size();
    r["playable_frames"] = points.size();
    r["frames_not_in_index"] = unindexed;
    r["thinned_frames"] = thinned;
    if (video.frames.size() >= 2)
        r["duration_s"] =
            1e-9 * static_cast<double>(video.frames.back().time_ns - video.frames.front().time_ns);
    const auto mean = [](const std::vector<double>& v) {
        double s = 0;
        for (double x : v) s += x;
        return v.empty() ? 0.0 : s / static_cast<double>(v.size());
    };
    r["points_mean"] = mean(points);
    r["bytes_mean"] = mean(bytes);
    // A binary PLY of the same points: float x y z + uchar r g b = 15 bytes per point.
    r["bytes_per_point"] = mean(points) > 0 ? mean(bytes) / mean(points) : 0.0;
    r["hub_ms_p50"] = quantile(hub, 0.5);
    r["hub_ms_p95"] = quantile(hub, 0.95);
    r["latency_ms_p50"] = quantile(latency, 0.5);
    r["latency_ms_p95"] = quantile(latency, 0.95);
    r["spread_ms_max"] = spread.empty() ? 0.0 : *std::max_element(spread.begin(), spread.end());
    if (video.header.contains("counters")) r["counters"] = video.header["counters"];
    r["problems"] = problems;
    return r;
}

/// rgbd-info DIR --frame N: one frame of a video as a view (world frame, coloured).
void export_video_frame(const std::string& path, long long frame, cli::Context& ctx) {
    const io::VideoInfo video = io::read_video(path);
    io::FrameMeta meta;
    io::Document document;
    document.cloud = io::to_point_cloud(io::read_video_frame(video, frame, &meta));
    document.cloud.view.id = static_cast<int>(frame);
    document.cloud.view.frame_index = meta.set;
    document.cloud.view.time_ns = meta.time_ns;
    document.cloud.view.source =
        (std::filesystem::path(path) / io::video_frame_file(frame)).string();
    ctx.metrics()["frame"] = frame;
    ctx.metrics()["points"] = document.cloud.size();
    ctx.write(document);
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

void run_info(cli::Context& ctx) {
    Report all = Report::array();
    std::vector<std::string> inputs = ctx.inputs();
    if (inputs.empty()) inputs.push_back("-");
    if (ctx.has("frame")) {
        if (inputs.size() != 1 || !fs::is_directory(inputs.front()))
            throw cli::UsageError("--frame N needs one video folder");
        if (ctx.output_path().empty() && isatty(STDOUT_FILENO))
            throw cli::UsageError("refusing to write binary PLY to a terminal: use -o FILE");
        export_video_frame(inputs.front(), ctx.get<long long>("frame"), ctx);
        return;
    }
    for (const std::string& input : inputs) {
        if (input != "-" && fs::is_directory(input) && fs::exists(fs::path(input) / "video.json")) {
            all.push_back(describe_video(input, ctx));
            continue;
        }
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
            if (docs.empty()) throw InputError(reader.name() + ": empty stream (no PLY document)");
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
}

const cli::ToolSpec kSpec{
    .name = "rgbd-info",
    .usage = "rgbd-info [--json] PATH...   |   rgbd-info VIDEO_DIR --frame N -o frame.ply",
    .description =
        "Prints a summary of each input: a capture folder (layout, sensors, frames, frame "
        "sets, ground truth), a view stream (per document: points, properties, metadata, "
        "bounding box, flag counts), a mesh (vertices, faces, border edges, closed, colours), "
        "a point file, or a 3D video folder (rgbd-capture --video: frames, duration, points "
        "and bytes per frame, hub ms and latency p50/p95, counters, and every frame file that "
        "is missing, stale or does not decode, by name). --frame N exports one video frame as "
        "a view for the rest of the pipeline.",
    .example = "rgbd-cloud cap/ | rgbd-info --json",
    .writes_stream = false,
    .writes_file = true,
    .add_options = [](cli::po::options_description& o) {
        o.add_options()("json", "print JSON instead of text")(
            "frame", cli::po::value<long long>()->value_name("N"),
            "with a 3D video folder: write its frame N as a view (binary PLY, world frame, "
            "coloured) to -o FILE or stdout instead of the summary");
    }};

}  // namespace

int main(int argc, char** argv) { return cli::run_tool(argc, argv, kSpec, run_info); }
