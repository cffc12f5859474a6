#include "cli/view_server.hpp"

#include <sys/socket.h>

#include <algorithm>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "cli/view_page.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli {

namespace fs = std::filesystem;
namespace beast = boost::beast;
namespace http = beast::http;
namespace asio = boost::asio;
using tcp = asio::ip::tcp;

fs::path find_three_dir(const fs::path& preferred) {
    fs::path dir = preferred;
    if (dir.empty()) {
        const char* env = std::getenv("RGBD_THREE_DIR");
        dir = env && *env ? fs::path(env) : fs::path("/usr/share/javascript/three");
    }
    for (const char* file : {"build/three.min.js", "examples/js/controls/OrbitControls.js"})
        if (!fs::exists(dir / file))
            throw IoError((dir / file).string() +
                          ": three.js not found (Debian package libjs-three, or RGBD_THREE_DIR)");
    return dir;
}

std::string encode_page_frame(std::int64_t frame, const io::ColoredPoints& points) {
    const std::uint32_t n = static_cast<std::uint32_t>(points.size());
    std::string out(16 + 15 * std::size_t{n}, '\0');
    std::memcpy(out.data(), "RGBDPTS1", 8);
    const std::uint32_t number = static_cast<std::uint32_t>(std::max<std::int64_t>(0, frame));
    std::memcpy(out.data() + 8, &n, 4);  // little-endian hosts
    std::memcpy(out.data() + 12, &number, 4);
    if (n) std::memcpy(out.data() + 16, points.xyz.data(), 12 * std::size_t{n});
    char* rgb = out.data() + 16 + 12 * std::size_t{n};
    for (std::uint32_t i = 0; i < n; ++i) {
        const Rgb c = i < points.rgb.size() ? points.rgb[i] : Rgb{200, 200, 200};
        rgb[3 * i] = static_cast<char>(c.r);
        rgb[3 * i + 1] = static_cast<char>(c.g);
        rgb[3 * i + 2] = static_cast<char>(c.b);
    }
    return out;
}

namespace {

std::string read_file(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path.string() + ": cannot open");
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

struct ViewServer::Impl {
    ViewServerOptions options;
    std::optional<fs::path> video_dir;
    std::optional<ViewModel> model;  // model mode (rgbd-view MODEL.glb)
    std::string three_js, orbit_js, gltf_js;
    asio::io_context io;
    tcp::acceptor acceptor{io};
    std::atomic<bool> stop{false};
    std::thread accept_thread;
    std::mutex mutex;  // sessions, fds, live frame
    std::vector<std::thread> sessions;
    std::set<int> fds;
    std::shared_ptr<const std::string> live;     // the newest frame's page encoding
    std::shared_ptr<const io::VideoInfo> video;  // the video's index as last read
    double live_time_s = 0;
    std::int64_t live_first_ns = -1;
    std::atomic<std::int64_t>* requests = nullptr;
    std::atomic<std::int64_t> frames_served{0}, last_frame{-1};  // GET /api/stats

    using Response = http::response<http::string_body>;

    Response reply(const http::request<http::string_body>& req, http::status status,
                   std::string body, const std::string& type) {
        Response res{status, req.version()};
        res.set(http::field::server, "rgbd-view");
        res.set(http::field::content_type, type);
        res.set(http::field::cache_control, "no-store");
        res.keep_alive(req.keep_alive());
        res.body() = std::move(body);
        res.prepare_payload();
        return res;
    }

    Response handle(const http::request<http::string_body>& req) {
        ++*requests;
        if (req.method() != http::verb::get && req.method() != http::verb::head)
            return reply(req, http::status::method_not_allowed, "GET only\n", "text/plain");
        std::string target(req.target());
        if (const auto q = target.find('?'); q != std::string::npos) target.resize(q);
        if (target == "/" || target == "/index.html")
            return reply(req, http::status::ok, model ? kModelPage : kViewPage,
                         "text/html; charset=utf-8");
        if (model && target == "/model.glb")
            return reply(req, http::status::ok, model->glb, "model/gltf-binary");
        if (model && target == "/GLTFLoader.js")
            return reply(req, http::status::ok, gltf_js, "application/javascript");
        if (model && target == "/api/info")
            return reply(req, http::status::ok, model->info_json, "application/json");
        if (target == "/three.min.js")
            return reply(req, http::status::ok, three_js, "application/javascript");
        if (target == "/OrbitControls.js")
            return reply(req, http::status::ok, orbit_js, "application/javascript");
        if (target == "/favicon.ico") return reply(req, http::status::no_content, "", "text/plain");
        if (target == "/api/info") return info(req);
        if (target == "/api/stats") {
            const nlohmann::json j = {{"requests", requests->load()},
                                      {"frames_served", frames_served.load()},
                                      {"last_frame", last_frame.load()}};
            return reply(req, http::status::ok, j.dump(), "application/json");
        }
        if (target == "/api/live") {
            std::shared_ptr<const std::string> frame;
            double time_s = 0;
            {
                std::lock_guard<std::mutex> lock(mutex);
                frame = live;
                time_s = live_time_s;
            }
            if (!frame) return reply(req, http::status::no_content, "", "text/plain");
            Response res = reply(req, http::status::ok, *frame, "application/octet-stream");
            res.set("X-Frame-Time-S", std::to_string(time_s));
            ++frames_served;
            return res;
        }
        const std::string prefix = "/api/frame/";
        if (target.rfind(prefix, 0) == 0 && video_dir) {
            std::int64_t number = -1;
            try {
                std::size_t used = 0;
                const std::string digits = target.substr(prefix.size());
                number = std::stoll(digits, &used);
                if (used != digits.size()) number = -1;
            } catch (...) {
            }
            if (number < 0)
                return reply(req, http::status::bad_request, "bad frame\n", "text/plain");
            try {
                std::shared_ptr<const io::VideoInfo> video = cached_video(false);
                const bool known =
                    std::any_of(video->frames.begin(), video->frames.end(),
                                [&](const io::VideoFrame& f) { return f.frame == number; });
                if (!known) video = cached_video(true);  // a growing video
                const io::ColoredPoints points = io::read_video_frame(*video, number);
                ++frames_served;
                last_frame = number;
                return reply(req, http::status::ok, encode_page_frame(number, points),
                             "application/octet-stream");
            } catch (const Error& e) {
                return reply(req, http::status::not_found, std::string(e.what()) + "\n",
                             "text/plain");
            }
        }
        return reply(req, http::status::not_found, "not found\n", "text/plain");
    }

    /// The video's index, read again when `refresh` (the page asks for the index) or never read.
    std::shared_ptr<const io::VideoInfo> cached_video(bool refresh) {
        {
            std::lock_guard<std::mutex> lock(mutex);
            if (video && !refresh) return video;
        }
        auto fresh = std::make_shared<const io::VideoInfo>(io::read_video(*video_dir));
        std::lock_guard<std::mutex> lock(mutex);
        video = fresh;
        return fresh;
    }

    Response info(const http::request<http::string_body>& req) {
        nlohmann::json j;
        if (!video_dir) {
            j = {{"mode", "live"}, {"frame_rate_hz", 30}};
        } else {
            try {
                const io::VideoInfo& video = *cached_video(true);
                j = {{"mode", "video"},
                     {"frame_rate_hz", video.frame_rate_hz},
                     {"complete", video.complete}};
                nlohmann::json list = nlohmann::json::array();
                for (const io::VideoFrame& f : video.frames)
                    list.push_back({{"frame", f.frame},
                                    {"time_ns", f.time_ns},
                                    {"points", f.points},
                                    {"ok", f.problem.empty()},
                                    {"problem", f.problem}});
                j["frames"] = list;
            } catch (const Error& e) {
                return reply(req, http::status::internal_server_error, std::string(e.what()) + "\n",
                             "text/plain");
            }
        }
        return reply(req, http::status::ok, j.dump(), "application/json");
    }

    void session(tcp::socket socket) {
        const int fd = socket.native_handle();
        beast::error_code ec;
        beast::flat_buffer buffer;
        while (!stop) {
            http::request<http::string_body> req;
            http::read(socket, buffer, req, ec);
            if (ec) break;
            Response res = handle(req);
            if (req.method() == http::verb::head) res.body().clear();
            http::write(socket, res, ec);
            if (ec || !res.keep_alive()) break;
        }
        socket.shutdown(tcp::socket::shutdown_send, ec);
        std::lock_guard<std::mutex> lock(mutex);
        fds.erase(fd);
    }

    void accept_loop() {
        while (!stop) {
            beast::error_code ec;
            tcp::socket socket(io);
            acceptor.accept(socket, ec);
            if (ec == asio::error::would_block || ec == asio::error::try_again) {
                std::this_thread::sleep_for(std::chrono::milliseconds(20));
                continue;
            }
            if (ec) continue;
            socket.non_blocking(false, ec);
            std::lock_guard<std::mutex> lock(mutex);
            if (stop) break;
            fds.insert(socket.native_handle());
            sessions.emplace_back(
                [this, s = std::move(socket)]() mutable { session(std::move(s)); });
        }
    }
};

ViewServer::ViewServer(const ViewServerOptions& options, std::optional<fs::path> video_dir)
    : ViewServer(options, std::move(video_dir), std::nullopt) {}

ViewServer::ViewServer(const ViewServerOptions& options, ViewModel model)
    : ViewServer(options, std::nullopt, std::move(model)) {}

ViewServer::ViewServer(const ViewServerOptions& options, std::optional<fs::path> video_dir,
                       std::optional<ViewModel> model)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.options = options;
    m.video_dir = std::move(video_dir);
    m.model = std::move(model);
    m.requests = &requests_;
    const fs::path three = find_three_dir(options.three_dir);
    m.three_js = read_file(three / "build/three.min.js");
    m.orbit_js = read_file(three / "examples/js/controls/OrbitControls.js");
    if (m.model) {
        const fs::path loader = three / "examples/js/loaders/GLTFLoader.js";
        if (!fs::exists(loader))
            throw IoError(loader.string() +
                          ": three.js's glTF loader not found (Debian package "
                          "libjs-three, or RGBD_THREE_DIR)");
        m.gltf_js = read_file(loader);
    }
    if (options.port < 0 || options.port > 65535)
        throw InputError("port must be 0..65535 (got " + std::to_string(options.port) + ")");
    beast::error_code ec;
    const auto address = asio::ip::make_address(options.bind, ec);
    if (ec) throw InputError("'" + options.bind + "' is not an IP address");
    const tcp::endpoint endpoint(address, static_cast<unsigned short>(options.port));
    m.acceptor.open(endpoint.protocol(), ec);
    if (!ec) m.acceptor.set_option(asio::socket_base::reuse_address(true), ec);
    if (!ec) m.acceptor.bind(endpoint, ec);
    if (!ec) m.acceptor.listen(asio::socket_base::max_listen_connections, ec);
    if (ec)
        throw IoError("cannot listen on " + options.bind + ":" + std::to_string(options.port) +
                      ": " + ec.message());
    m.acceptor.non_blocking(true);
    port_ = m.acceptor.local_endpoint().port();
    m.accept_thread = std::thread([&m] { m.accept_loop(); });
}

ViewServer::~ViewServer() { stop(); }

void ViewServer::stop() {
    if (!impl_) return;
    Impl& m = *impl_;
    if (m.stop.exchange(true)) return;
    if (m.accept_thread.joinable()) m.accept_thread.join();
    std::vector<std::thread> sessions;
    {
        std::lock_guard<std::mutex> lock(m.mutex);
        for (const int fd : m.fds) ::shutdown(fd, SHUT_RDWR);  // wakes blocked reads
        sessions.swap(m.sessions);
    }
    for (auto& t : sessions)
        if (t.joinable()) t.join();
    beast::error_code ec;
    m.acceptor.close(ec);
}

void ViewServer::publish(std::int64_t frame, const io::VideoFrame& info,
                         const io::ColoredPoints& points) {
    auto encoded = std::make_shared<const std::string>(encode_page_frame(frame, points));
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->live_first_ns < 0) impl_->live_first_ns = info.time_ns;
    impl_->live_time_s = 1e-9 * static_cast<double>(info.time_ns - impl_->live_first_ns);
    impl_->live = std::move(encoded);
}

}  // namespace rgbd::cli
