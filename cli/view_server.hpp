// The 3D video web viewer (issue 20): a small HTTP server (Boost.Beast) that serves one page
// playing a video folder (rgbd-view) or the live fused stream of a running hub
// (rgbd-capture --serve), with three.js from Debian's libjs-three served by the tool itself
// (no network access needed). A model (rgbd-view MODEL.glb) is served as its glTF binary
// (GET /model.glb) and drawn by three.js's GLTFLoader, with its texture. Frames are decoded from
// Draco here and sent to the page as flat arrays (GET /api/frame/N, /api/live: "RGBDPTS1", uint32
// points, uint32 frame number, float32 x y z per point, then uint8 r g b per point). A frame file
// that does not decode is answered 404 and the page skips it. GET /api/stats: requests, frames
// served, the last one. Listens on 127.0.0.1 unless told another address.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "io/video.hpp"

namespace rgbd::cli {

struct ViewServerOptions {
    std::string bind = "127.0.0.1";  ///< address to listen on
    int port = 8080;                 ///< 0 = any free port (see ViewServer::port())
    /// Folder of Debian's libjs-three (build/three.min.js, examples/js/controls/...);
    /// empty = $RGBD_THREE_DIR or /usr/share/javascript/three.
    std::filesystem::path three_dir;
};

/// The folder of three.js; IoError naming the missing file when it is not installed.
std::filesystem::path find_three_dir(const std::filesystem::path& preferred);

/// A textured model for the page (rgbd-view MODEL.glb): served as GET /model.glb.
struct ViewModel {
    std::string glb;        ///< the glTF binary's bytes
    std::string info_json;  ///< the body of GET /api/info ("mode": "model", counts, up)
};

class ViewServer {
public:
    /// Serves `video_dir` (a video folder, re-read when the page asks for the index, so a
    /// growing video plays to its end) or, without one, the live frames given to publish().
    /// Throws IoError when it cannot listen (address in use, bad address).
    ViewServer(const ViewServerOptions& options, std::optional<std::filesystem::path> video_dir);
    /// Serves one model: the model page, /model.glb and /GLTFLoader.js (IoError naming the
    /// file when libjs-three has no examples/js/loaders/GLTFLoader.js).
    ViewServer(const ViewServerOptions& options, ViewModel model);
    ~ViewServer();
    ViewServer(const ViewServer&) = delete;
    ViewServer& operator=(const ViewServer&) = delete;

    /// Live mode: the newest fused frame (thread-safe; the page fetches the newest only).
    void publish(std::int64_t frame, const io::VideoFrame& info, const io::ColoredPoints& points);
    /// The port listened on.
    int port() const { return port_; }
    std::int64_t requests() const { return requests_; }
    /// Stops accepting, closes open connections and joins the threads.
    void stop();

private:
    ViewServer(const ViewServerOptions& options, std::optional<std::filesystem::path> video_dir,
               std::optional<ViewModel> model);
    struct Impl;
    std::unique_ptr<Impl> impl_;
    int port_ = 0;
    std::atomic<std::int64_t> requests_{0};
};

/// The binary frame of the page ("RGBDPTS1" ...).
std::string encode_page_frame(std::int64_t frame, const io::ColoredPoints& points);

}  // namespace rgbd::cli
