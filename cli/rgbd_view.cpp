// rgbd-view: plays a 3D video folder (rgbd-capture --video) in a web browser (issue 20). Serves
// one page with three.js (Debian's libjs-three, served by the tool itself) on localhost; the
// page plays, pauses and scrubs the video, orbits, and shows frame number, time and point
// count. Frames that are missing or do not decode are skipped (rgbd-info DIR names them).
// Given a model file instead (.glb; .obj, .ply, .off are converted to glTF binary in memory),
// it shows the model with its texture (issue 36) through three.js's GLTFLoader.
#include <unistd.h>

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cmath>
#include <csignal>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "cli/common/tool.hpp"
#include "cli/view_server.hpp"
#include "io/textured_mesh_io.hpp"
#include "io/video.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

namespace fs = std::filesystem;

/// A direction of --up or --front: x, +y, -z, ... or X,Y,Z.
std::array<double, 3> parse_up(const std::string& text, const std::string& option) {
    const std::string axes = "xyz";
    const bool negative = !text.empty() && text[0] == '-';
    const std::string axis =
        text.empty() || (text[0] != '-' && text[0] != '+') ? text : text.substr(1);
    if (axis.size() == 1 && axes.find(axis[0]) != std::string::npos) {
        std::array<double, 3> up{0, 0, 0};
        up[axes.find(axis[0])] = negative ? -1 : 1;
        return up;
    }
    const auto v = cli::parse_doubles(text, option);
    if (v.size() != 3)
        throw cli::UsageError("--" + option + ": give an axis (x, -y, ...) or X,Y,Z");
    if (!std::isfinite(v[0] + v[1] + v[2]) || v[0] * v[0] + v[1] * v[1] + v[2] * v[2] == 0)
        throw cli::UsageError("--" + option + " must be finite and non-zero");
    return {v[0], v[1], v[2]};
}

/// The model of a .glb (as it is) or of another mesh file (converted to glTF binary) for the
/// page; errors name the file.
cli::ViewModel load_model(const fs::path& path,
                          const std::optional<std::array<double, 3>>& up_given,
                          const std::optional<std::array<double, 3>>& front_given,
                          cli::Context& ctx) {
    const TexturedMesh mesh = io::read_textured_mesh(path);  // checks it; errors name it
    // --up and --front are in the model's coordinates. A .glb whose root node turns its up to
    // +Y (the toolkit's, from the capture's cameras) is drawn turned by three.js, so both turn
    // alike; --up defaults to the file's up, then y. The default front is chosen as the page
    // does (+z, +x, -z, -x: the first least aligned with up), before the turn.
    using Vec = Eigen::Vector3d;
    const auto vec = [](const std::array<double, 3>& a) { return Vec(a[0], a[1], a[2]); };
    const Vec up_model = up_given ? vec(*up_given) : mesh.up ? *mesh.up : Vec::UnitY();
    const Eigen::Matrix3d turn =
        mesh.up ? io::gltf_up_rotation(*mesh.up) : Eigen::Matrix3d::Identity();
    const auto array = [](const Vec& v) { return std::array<double, 3>{v.x(), v.y(), v.z()}; };
    const std::array<double, 3> up = array(turn * up_model);
    std::optional<std::array<double, 3>> front;
    if (front_given) {
        front = array(turn * vec(*front_given));
    } else if (mesh.up) {
        const Vec u = up_model.normalized();
        Vec best = Vec::UnitZ();
        for (const Vec& v :
             std::array<Vec, 4>{Vec::UnitZ(), Vec::UnitX(), -Vec::UnitZ(), -Vec::UnitX()})
            if (std::abs(v.dot(u)) < std::abs(best.dot(u)) - 1e-9) best = v;
        front = array(turn * best);
    }
    fs::path glb = path;
    std::string ext = path.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const bool convert = ext != ".glb";
    if (convert) {
        glb = fs::temp_directory_path() /
              ("rgbd-view-" + std::to_string(::getpid()) + "-" + path.stem().string() + ".glb");
        io::write_textured_mesh(glb, mesh, "rgbd-view");
    }
    std::ifstream in(glb, std::ios::binary);
    cli::ViewModel model;
    model.glb.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    const bool read_ok = static_cast<bool>(in) || in.eof();
    if (convert) fs::remove(glb);
    if (!read_ok || model.glb.empty()) throw IoError(path.string() + ": cannot read");
    nlohmann::json info = {{"mode", "model"},
                           {"file", path.filename().string()},
                           {"vertices", mesh.vertices.size()},
                           {"triangles", mesh.faces.size()},
                           {"textured", mesh.has_texture()},
                           {"atlases", mesh.atlases.size()},
                           {"up", up}};
    if (front) info["front"] = *front;
    model.info_json = info.dump();
    ctx.metrics()["model"] = info;
    return model;
}

bool is_model_file(const fs::path& path) {
    if (fs::is_directory(path)) return false;
    std::string ext = path.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext == ".glb" || ext == ".obj" || ext == ".ply" || ext == ".off";
}

void run_view(cli::Context& ctx) {
    if (ctx.inputs().size() != 1)
        throw cli::UsageError(
            "give one video folder (rgbd-capture --video DIR) or one model (.glb, .obj, .ply)");
    const std::string dir = ctx.inputs().front();
    // The options first: a bad value is a usage error before the video is read.
    cli::ViewServerOptions options;
    options.port = ctx.get<int>("port");
    options.bind = ctx.get<std::string>("bind");
    if (options.port < 0 || options.port > 65535) throw cli::UsageError("--port must be 0..65535");
    const double duration_s = ctx.get<double>("duration-s");
    if (!(duration_s >= 0)) throw cli::UsageError("--duration-s must be >= 0");
    std::optional<std::array<double, 3>> up;
    if (!ctx.options()["up"].defaulted()) up = parse_up(ctx.get<std::string>("up"), "up");
    std::optional<std::array<double, 3>> front;
    if (ctx.options().count("front")) front = parse_up(ctx.get<std::string>("front"), "front");
    const bool model_mode = is_model_file(dir);
    std::optional<cli::ViewModel> model;
    io::VideoInfo video;
    std::size_t playable = 0;
    if (model_mode) {
        model = load_model(dir, up, front, ctx);
    } else {
        video = io::read_video(dir);  // errors name the folder
        for (const io::VideoFrame& f : video.frames) playable += f.problem.empty();
    }
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    std::unique_ptr<cli::ViewServer> served =
        model ? std::make_unique<cli::ViewServer>(options, std::move(*model))
              : std::make_unique<cli::ViewServer>(options, std::filesystem::path(dir));
    cli::ViewServer& server = *served;
    const std::string url = "http://" + options.bind + ":" + std::to_string(server.port()) + "/";
    if (model_mode)
        ctx.note("showing " + dir + " at " + url);
    else
        ctx.note("playing " + dir + " (" + std::to_string(playable) + " of " +
                 std::to_string(video.frames.size()) + " frames playable) at " + url);
    std::cout << url << std::endl;  // for scripts that asked for port 0
    const auto start = std::chrono::steady_clock::now();
    while (!g_stop) {
        if (duration_s > 0 &&
            std::chrono::steady_clock::now() - start > std::chrono::duration<double>(duration_s))
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    server.stop();
    ctx.metrics()["requests"] = server.requests();
    ctx.metrics()["port"] = server.port();
    if (!model_mode) {
        ctx.metrics()["frames"] = video.frames.size();
        ctx.metrics()["playable_frames"] = playable;
    }
}

}  // namespace

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-view";
    spec.usage = "rgbd-view DIR|MODEL.glb [--port P] [--bind ADDRESS] [--up AXIS] [--front AXIS]";
    spec.description =
        "Plays a 3D video folder (rgbd-capture --video DIR) in a web browser: serves a page "
        "with three.js (Debian's libjs-three, served by this tool; $RGBD_THREE_DIR overrides "
        "the folder) that plays, pauses and scrubs the video, orbits with the mouse, and shows "
        "the frame number, time and point count. Listens on 127.0.0.1 (this machine only) "
        "unless --bind names another address. Frames that are missing or do not decode are "
        "skipped; rgbd-info DIR names them. Given a model instead (.glb, or .obj/.ply/.off, "
        "converted to glTF binary in memory), shows it with its texture or vertex colours "
        "(three.js's GLTFLoader), lit as rgbd-render draws, up along --up, seen from a "
        "three-quarter view of --front. Runs until "
        "SIGINT/SIGTERM or --duration-s.";
    spec.example =
        "rgbd-view take1/ --port 8080   # then open http://127.0.0.1:8080/; rgbd-view model.glb";
    spec.reads_stream = false;
    spec.writes_stream = false;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("port", cli::value<int>(8080, "PORT"),
                        "port to listen on (0 = any free port; the URL is printed)")(
            "bind", cli::value<std::string>("127.0.0.1", "ADDRESS"),
            "address to listen on (0.0.0.0 lets other machines in)")(
            "duration-s", cli::value<double>(0.0, "S"),
            "stop after S seconds (0 = until a signal)")(
            "up", cli::value<std::string>("y", "AXIS|X,Y,Z"),
            "a model's up direction in its coordinates (x, -y, ... or X,Y,Z; default: the "
            "up a .glb of this toolkit records, else y)")(
            "front", cli::value<std::string>("AXIS|X,Y,Z"),
            "the side of a model to face the viewer (default: +z, +x, -z or -x, the one least "
            "aligned with up)");
    };
    return cli::run_tool(argc, argv, spec, [](cli::Context& ctx) { run_view(ctx); });
}
