// rgbd-view: plays a 3D video folder (rgbd-capture --video) in a web browser (issue 20). Serves
// one page with three.js (Debian's libjs-three, served by the tool itself) on localhost; the
// page plays, pauses and scrubs the video, orbits, and shows frame number, time and point
// count. Frames that are missing or do not decode are skipped (rgbd-info DIR names them).
#include <atomic>
#include <csignal>
#include <iostream>
#include <thread>

#include "cli/common/tool.hpp"
#include "cli/view_server.hpp"
#include "io/video.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

void run_view(cli::Context& ctx) {
    if (ctx.inputs().size() != 1)
        throw cli::UsageError("give one video folder (rgbd-capture --video DIR)");
    const std::string dir = ctx.inputs().front();
    // The options first: a bad value is a usage error before the video is read.
    cli::ViewServerOptions options;
    options.port = ctx.get<int>("port");
    options.bind = ctx.get<std::string>("bind");
    if (options.port < 0 || options.port > 65535) throw cli::UsageError("--port must be 0..65535");
    const double duration_s = ctx.get<double>("duration-s");
    if (!(duration_s >= 0)) throw cli::UsageError("--duration-s must be >= 0");
    const io::VideoInfo video = io::read_video(dir);  // errors name the folder
    std::size_t playable = 0;
    for (const io::VideoFrame& f : video.frames) playable += f.problem.empty();
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    cli::ViewServer server(options, std::filesystem::path(dir));
    const std::string url = "http://" + options.bind + ":" + std::to_string(server.port()) + "/";
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
    ctx.metrics()["frames"] = video.frames.size();
    ctx.metrics()["playable_frames"] = playable;
}

}  // namespace

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-view";
    spec.usage = "rgbd-view DIR [--port P] [--bind ADDRESS]";
    spec.description =
        "Plays a 3D video folder (rgbd-capture --video DIR) in a web browser: serves a page "
        "with three.js (Debian's libjs-three, served by this tool; $RGBD_THREE_DIR overrides "
        "the folder) that plays, pauses and scrubs the video, orbits with the mouse, and shows "
        "the frame number, time and point count. Listens on 127.0.0.1 (this machine only) "
        "unless --bind names another address. Frames that are missing or do not decode are "
        "skipped; rgbd-info DIR names them. Runs until SIGINT/SIGTERM or --duration-s.";
    spec.example = "rgbd-view take1/ --port 8080   # then open http://127.0.0.1:8080/";
    spec.reads_stream = false;
    spec.writes_stream = false;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("port", cli::value<int>(8080, "PORT"),
                        "port to listen on (0 = any free port; the URL is printed)")(
            "bind", cli::value<std::string>("127.0.0.1", "ADDRESS"),
            "address to listen on (0.0.0.0 lets other machines in)")(
            "duration-s", cli::value<double>(0.0, "S"),
            "stop after S seconds (0 = until a signal)");
    };
    return cli::run_tool(argc, argv, spec, [](cli::Context& ctx) { run_view(ctx); });
}
