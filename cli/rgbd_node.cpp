// rgbd-node: one sensor -> the capture hub (docs/algorithms.md §1, docs/algorithms.md §1). Reads
// frames from a sensor (a recording played back in real time, the synthetic sensor, a device),
// compresses depth losslessly (RVL) and colour as JPEG, and pushes them to rgbd-capture over
// ZeroMQ; a second socket answers the hub's clock probes so they never wait behind frames.
// For tests the node can run on a deliberately wrong clock (--clock-offset-ms,
// --clock-drift-ppm): its time stamps are then in that clock, as on a PC whose clock is off.
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>
#include <zmq.hpp>

#include "cli/common/tool.hpp"
#include "cli/node_views.hpp"
#include "cli/zmq_errors.hpp"
#include "io/image_codec.hpp"
#include "io/rvl.hpp"
#include "sensors/network/protocol.hpp"
#include "sensors/network/transport.hpp"
#include "sensors/registry.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace net = rgbd::sensors::net;

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

/// The node's clock: the machine's monotonic clock shifted by an offset and running fast or
/// slow by a drift (both zero unless injected for testing).
struct NodeClock {
    std::int64_t epoch_ns = 0;  ///< monotonic instant where the drift term is zero
    double offset_ns = 0;
    double drift_ppm = 0;
    std::int64_t at(std::int64_t monotonic) const {
        const double drift = drift_ppm * 1e-6 * static_cast<double>(monotonic - epoch_ns);
        return monotonic + static_cast<std::int64_t>(std::llround(offset_ns + drift));
    }
    std::int64_t now() const { return at(sensors::monotonic_ns()); }
    /// The monotonic instant at which the node's clock reads `node_ns` (inverse of at()).
    std::int64_t monotonic_at(std::int64_t node_ns) const {
        std::int64_t m = node_ns - static_cast<std::int64_t>(std::llround(offset_ns));
        for (int i = 0; i < 3; ++i) m += node_ns - at(m);
        return m;
    }
};

/// Answers clock probes and says hello until the hub says start; runs on its own thread with
/// its own socket.
class ControlChannel {
public:
    ControlChannel(zmq::context_t& context, const std::string& endpoint, const NodeClock& clock,
                   std::uint64_t session, std::string hello_json, const net::CurveKeys* keys)
        : socket_(context, zmq::socket_type::dealer),
          clock_(clock),
          session_(session),
          hello_(std::move(hello_json)) {
        socket_.set(zmq::sockopt::linger, 1000);
        if (keys) net::make_curve_client(socket_, *keys);
        socket_.connect(endpoint);
        thread_ = std::thread([this] { run(); });
    }
    ~ControlChannel() {
        stop_ = true;
        if (thread_.joinable()) thread_.join();
    }
    bool started() const { return started_; }
    /// The start message: first frame's instant (node clock, 0 = at once), the rig's frame
    /// period (ns) and its JSON. Valid once started().
    void start(std::int64_t& instant, std::int64_t& period, std::string& json) {
        std::lock_guard<std::mutex> lock(mutex_);
        instant = start_ns_;
        period = period_ns_;
        json = start_json_;
    }
    std::int64_t probes() const { return probes_; }
    /// Queues a bye (sent by the control thread, which owns the socket).
    /// Sent three times, 50 ms apart, so that one lost message does not keep the hub waiting.
    void bye(std::int64_t frames) {
        frames_ = frames;
        bye_ = true;
        for (int i = 0; i < 100 && byes_sent_ < 3; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }

private:
    void send(const net::ControlMessage& m) {
        const auto bytes = net::encode_control(m);
        socket_.send(zmq::buffer(bytes), zmq::send_flags::dontwait);
    }
    void run() {
        std::int64_t last_hello = 0, last_bye = 0;
        zmq::message_t message;
        while (!stop_) {
            const std::int64_t now = sensors::monotonic_ns();
            // Hello every second until started, then every 5 s: after a reconnect the hub
            // learns the node's new address from it.
            if (now - last_hello > (started_ ? 5'000'000'000 : 1'000'000'000)) {
                net::ControlMessage hello;
                hello.type = net::ControlType::kHello;
                hello.session = session_;
                hello.json = hello_;
                send(hello);
                last_hello = now;
            }
            if (bye_ && byes_sent_ < 3 && now - last_bye >= 50'000'000) {
                net::ControlMessage bye;
                bye.type = net::ControlType::kBye;
                bye.session = session_;
                bye.frames = frames_;
                send(bye);
                ++byes_sent_;
                last_bye = now;
            }
            zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
            try {
                if (zmq::poll(&item, 1, std::chrono::milliseconds(20)) == 0) continue;
            } catch (const zmq::error_t&) {
                continue;  // EINTR: a signal; the main thread decides
            }
            while (socket_.recv(message, zmq::recv_flags::dontwait)) {
                const std::int64_t t1 = clock_.now();
                net::ControlMessage in;
                std::string error;
                if (!net::parse_control(static_cast<const std::uint8_t*>(message.data()),
                                        message.size(), in, error))
                    continue;
                if (in.type == net::ControlType::kProbe) {
                    net::ControlMessage reply;
                    reply.type = net::ControlType::kProbeReply;
                    reply.seq = in.seq;
                    reply.t0 = in.t0;
                    reply.t1 = t1;
                    reply.t2 = clock_.now();
                    send(reply);
                    ++probes_;
                } else if (in.type == net::ControlType::kStart && !started_) {
                    {
                        std::lock_guard<std::mutex> lock(mutex_);
                        start_ns_ = in.t0;
                        period_ns_ = in.t1;
                        start_json_ = in.json;
                    }
                    started_ = true;
                }
            }
        }
    }
    zmq::socket_t socket_;
    NodeClock clock_;
    std::uint64_t session_;
    std::string hello_;
    std::atomic<bool> stop_{false}, started_{false}, bye_{false};
    std::atomic<int> byes_sent_{0};
    std::atomic<std::int64_t> probes_{0}, frames_{0};
    std::mutex mutex_;
    std::int64_t start_ns_ = 0, period_ns_ = 0;
    std::string start_json_;
    std::thread thread_;
};

void run_node(cli::Context& ctx) {
    if (!ctx.inputs().empty())
        throw cli::UsageError("unexpected argument '" + ctx.inputs().front() +
                              "' (the sensor is given with --sensor)");
    if (!ctx.has("sensor")) throw cli::UsageError("--sensor is required (e.g. playback:cap#k2-0)");
    const double offset_ms = ctx.get<double>("clock-offset-ms");
    const double drift_ppm = ctx.get<double>("clock-drift-ppm");
    if (!std::isfinite(offset_ms) || std::abs(offset_ms) > 3.6e6)
        throw cli::UsageError("--clock-offset-ms must be within +-3.6e6");
    if (!std::isfinite(drift_ppm) || std::abs(drift_ppm) > 1000)
        throw cli::UsageError("--clock-drift-ppm must be within +-1000");
    const int quality = ctx.get<int>("jpeg-quality");
    if (quality < 1 || quality > 100) throw cli::UsageError("--jpeg-quality must be 1..100");
    const auto frames_limit = ctx.get<std::int64_t>("frames");
    const double duration_s = ctx.get<double>("duration-s");
    if (frames_limit < 0) throw cli::UsageError("--frames must be >= 0");
    if (!(duration_s >= 0)) throw cli::UsageError("--duration-s must be >= 0");
    const double start_timeout_s = ctx.get<double>("start-timeout-s");
    const double work_delay_ms = ctx.get<double>("work-delay-ms");
    if (!(work_delay_ms >= 0 && work_delay_ms <= 10000))
        throw cli::UsageError("--work-delay-ms must be in [0, 10000]");
    const auto work_delay_ns = static_cast<std::int64_t>(work_delay_ms * 1e6);

    const std::string hub = ctx.get<std::string>("hub");
    const std::string control =
        ctx.has("control") ? ctx.get<std::string>("control") : net::control_endpoint_for(hub);
    std::unique_ptr<net::CurveKeys> keys;
    if (ctx.has("key")) {
        if (!net::curve_available())
            throw IoError("--key: this libzmq has no CURVE support (zmq_has(\"curve\") is 0)");
        keys = std::make_unique<net::CurveKeys>(net::read_key_file(ctx.get<std::string>("key")));
    }

    sensors::OpenOptions open;
    open.max_frames = frames_limit;
    open.playback.loop = ctx.has("loop");
    open.playback.align_to_clock = !ctx.has("no-align");
    open.playback.decode_color = ctx.has("views");
    auto sensor = sensors::open_sensor(ctx.get<std::string>("sensor"), open);
    const io::SensorSpec& spec = sensor->spec();
    if (spec.id.size() > net::kMaxSensorId)
        throw InputError("sensor id '" + spec.id + "' is longer than " +
                         std::to_string(net::kMaxSensorId) + " bytes");

    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);

    NodeClock clock;
    clock.epoch_ns = sensors::monotonic_ns();
    clock.offset_ns = offset_ms * 1e6;
    clock.drift_ppm = drift_ppm;
    std::random_device rd;
    const std::uint64_t session =
        (static_cast<std::uint64_t>(rd()) << 32) ^ rd() ^ static_cast<std::uint64_t>(::getpid());

    std::unique_ptr<std::ofstream> truth;
    if (ctx.has("truth")) {
        truth = std::make_unique<std::ofstream>(ctx.get<std::string>("truth"));
        if (!*truth) throw IoError(ctx.get<std::string>("truth") + ": cannot open for writing");
        *truth << "session,index,source_position,true_ns,node_ns\n";
    }

    zmq::context_t context(1);
    zmq::socket_t push(context, zmq::socket_type::push);
    push.set(zmq::sockopt::sndhwm, 2000);
    push.set(zmq::sockopt::sndtimeo, static_cast<int>(ctx.get<double>("send-timeout-s") * 1000));
    push.set(zmq::sockopt::linger, 10000);
    if (keys) net::make_curve_client(push, *keys);
    try {
        push.connect(hub);
    } catch (const zmq::error_t& e) {
        throw InputError("--hub " + hub + ": " + e.what());
    }
    const nlohmann::json hello = {{"sensor", spec.id},
                                  {"rate_hz", sensor->frame_rate_hz()},
                                  {"width", spec.depth.width},
                                  {"height", spec.depth.height},
                                  {"pid", ::getpid()}};
    std::unique_ptr<ControlChannel> channel;
    try {
        channel = std::make_unique<ControlChannel>(context, control, clock, session, hello.dump(),
                                                   keys.get());
    } catch (const zmq::error_t& e) {
        throw InputError("--control " + control + ": " + e.what());
    }
    ctx.info("session " + std::to_string(session) + ": waiting for the hub at " + control);
    const std::int64_t wait_start = sensors::monotonic_ns();
    while (!channel->started() && !g_stop) {
        if (start_timeout_s > 0 &&
            sensors::monotonic_ns() - wait_start > static_cast<std::int64_t>(start_timeout_s * 1e9))
            throw IoError("no answer from the hub at " + control + " within " +
                          format_number(start_timeout_s) +
                          " s (wrong address, hub not running, "
                          "or a key mismatch)");
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }

    std::int64_t start_node_ns = 0, period_ns = 0;
    std::string start_json;
    channel->start(start_node_ns, period_ns, start_json);

    // The hub may ask for fused-ready views instead of frames (rgbd-capture --video
    // --fuse-on nodes): the per-view work then runs here, on the node's own CPU.
    const std::optional<cli::ViewRequest> views = cli::view_request_from_json(start_json);
    io::SensorSpec view_spec = spec;
    pipeline::VideoFusionOptions fusion;
    if (views) {
        view_spec.world_from_depth = views->world_from_sensor;
        view_spec.has_world_from_depth = true;
        fusion.extraction.crop_radius_m = views->crop_radius_m;
        fusion.clean = views->clean;
        ctx.info("the hub asks for views: per-view work on this node");
    }
    const bool send_color = !ctx.has("no-color");
    cv::Mat decoded;
    std::int64_t view_points = 0, views_made = 0;
    // One frame -> the view payloads (points in `xyz`, colours in `rgb`).
    const auto make_view = [&](const sensors::SensorFrame& f, std::vector<std::uint8_t>& xyz,
                               std::vector<std::uint8_t>& rgb) {
        const cv::Mat* bgr = &f.color;
        if (f.color.empty() && !f.color_jpeg.empty()) {
            try {
                decoded = io::decode_image(f.color_jpeg, io::ImageMode::kColor);
            } catch (const IoError& e) {
                throw InputError("cannot decode the colour of frame " + std::to_string(f.index) +
                                 ": " + e.what());
            }
            bgr = &decoded;
        }
        RgbdFrame rgbd =
            io::frame_from_stored(view_spec, f.depth, send_color ? *bgr : cv::Mat(),
                                  "frame " + std::to_string(f.index) + " of sensor " + spec.id);
        rgbd.frame_index = f.index;
        const PointCloud view = pipeline::fusion_view(rgbd, 0, fusion, views->centre);
        cli::encode_view_payload(view, xyz, rgb);
        ++views_made;
    };
    // --cache-views (benchmarks): the view of every recording position is made once, before
    // the start (give the hub a long --start-lead-ms), and sent again on every loop, so that
    // many nodes on one machine load the hub, not the machine.
    const bool cache_views = views && ctx.has("cache-views");
    std::map<std::int64_t, std::pair<std::vector<std::uint8_t>, std::vector<std::uint8_t>>> cache;
    if (cache_views) {
        sensors::OpenOptions all = open;
        all.max_frames = 0;
        all.playback.realtime = false;
        all.playback.loop = false;
        auto copy = sensors::open_sensor(ctx.get<std::string>("sensor"), all);
        sensors::SensorFrame f;
        while (!g_stop && copy->next(f)) {
            if (f.source_position < 0)
                throw cli::UsageError("--cache-views needs a playback sensor");
            auto& entry = cache[f.source_position];
            make_view(f, entry.first, entry.second);
        }
        ctx.info("made the views of " + std::to_string(cache.size()) + " recording positions");
    }

    // The hub's common start instant (node clock) -> this machine's monotonic clock; an
    // instant already past (a start message sent again after a reconnect, a slow cache)
    // moves along the frame grid to the next one ahead.
    bool start_honoured = false;
    std::int64_t start_monotonic = 0;
    if (start_node_ns != 0) {
        start_monotonic = clock.monotonic_at(start_node_ns);
        const std::int64_t now = sensors::monotonic_ns() + 5'000'000;
        if (start_monotonic < now && period_ns > 0)
            start_monotonic += (now - start_monotonic + period_ns - 1) / period_ns * period_ns;
        start_honoured = sensor->start_at(start_monotonic);
    }

    sensors::SensorFrame frame;
    std::vector<std::uint8_t> rvl, jpeg, message;
    std::int64_t sent = 0, raw_bytes = 0, rvl_bytes = 0, color_bytes = 0;
    double encode_s = 0;
    const std::int64_t run_start = sensors::monotonic_ns();
    while (!g_stop) {
        if (duration_s > 0 &&
            sensors::monotonic_ns() - run_start > static_cast<std::int64_t>(duration_s * 1e9))
            break;
        if (!sensor->next(frame)) break;
        const std::int64_t t_encode = sensors::monotonic_ns();
        const std::size_t pixels = frame.depth.total();
        if (!frame.depth.isContinuous()) frame.depth = frame.depth.clone();
        const std::vector<std::uint8_t>* color = &frame.color_jpeg;
        const auto cached = cache_views && frame.source_position >= 0
                                ? cache.find(frame.source_position)
                                : cache.end();
        if (cached != cache.end()) {
            rvl = cached->second.first;
            jpeg = cached->second.second;
            color = &jpeg;
            view_points += static_cast<std::int64_t>(rvl.size() / 12);
        } else if (views) {
            make_view(frame, rvl, jpeg);
            color = &jpeg;
            view_points += static_cast<std::int64_t>(rvl.size() / 12);
        } else {
            io::rvl_compress(frame.depth.ptr<std::uint16_t>(), pixels, rvl);
            if (!send_color) {
                jpeg.clear();
                color = &jpeg;
            } else if (frame.color_jpeg.empty() && !frame.color.empty()) {
                try {
                    jpeg = io::encode_jpeg(frame.color, quality);
                } catch (const Error& e) {
                    throw AlgorithmError("cannot JPEG-encode colour frame " +
                                         std::to_string(frame.index) + ": " + e.what());
                }
                color = &jpeg;
            }
        }
        net::FrameHeader header;
        header.kind = views ? net::PayloadKind::kView : net::PayloadKind::kFrame;
        header.session = session;
        header.sensor_id = spec.id;
        header.index = frame.index;
        header.device_ns = frame.device_ns;
        header.node_ns = clock.at(frame.capture_ns);
        header.width = static_cast<std::uint16_t>(frame.depth.cols);
        header.height = static_cast<std::uint16_t>(frame.depth.rows);
        if (work_delay_ns > 0) {  // testing: a node whose per-frame work is slow
            std::this_thread::sleep_for(std::chrono::nanoseconds(work_delay_ns));
        }
        header.sent_ns = clock.now();  // the hub sees how far behind its sensor the node is
        net::encode_frame(header, rvl.data(), rvl.size(), color->data(), color->size(), message);
        encode_s += 1e-9 * static_cast<double>(sensors::monotonic_ns() - t_encode);
        bool accepted = false;
        try {
            accepted = push.send(zmq::buffer(message), zmq::send_flags::none).has_value();
        } catch (const zmq::error_t& e) {
            if (e.num() != EINTR) throw;
            if (g_stop) break;
        }
        if (!accepted) {
            if (g_stop) break;
            push.set(zmq::sockopt::linger, 0);  // nobody takes the queued frames: do not wait
            throw IoError("the hub at " + hub + " accepts no frames (send timed out)");
        }
        if (truth)
            *truth << session << ',' << frame.index << ',' << frame.source_position << ','
                   << frame.capture_ns << ',' << header.node_ns << '\n'
                   << std::flush;  // tests read it while the node runs
        ++sent;
        raw_bytes += static_cast<std::int64_t>(pixels * 2);
        rvl_bytes += static_cast<std::int64_t>(rvl.size());
        color_bytes += static_cast<std::int64_t>(color->size());
    }
    // Stopped by a signal: give queued frames a second to leave, not the full linger.
    if (g_stop) push.set(zmq::sockopt::linger, 1000);
    channel->bye(sent);
    if (truth) {
        truth->flush();
        if (!*truth) throw IoError(ctx.get<std::string>("truth") + ": write failed");
    }
    auto& m = ctx.metrics();
    m["sensor"] = spec.id;
    m["session"] = session;
    m["frames_sent"] = sent;
    m["probes_answered"] = channel->probes();
    m["start_monotonic_ns"] = start_monotonic;
    m["start_honoured"] = start_honoured;
    m["clock_offset_ns"] = clock.offset_ns;
    m["clock_drift_ppm"] = clock.drift_ppm;
    m["clock_epoch_ns"] = clock.epoch_ns;
    m["rvl_ratio"] = rvl_bytes > 0 ? static_cast<double>(raw_bytes) / rvl_bytes : 0.0;
    m["color_bytes"] = color_bytes;
    m["encode_ms_per_frame"] = sent > 0 ? 1e3 * encode_s / sent : 0.0;
    m["payload"] = views ? "views" : "frames";
    if (views) {
        m["view_points_per_frame"] = sent > 0 ? double(view_points) / sent : 0.0;
        m["views_made"] = views_made;
    }
    // CPU of the whole node (user + system, all threads) per frame sent.
    rusage usage{};
    if (::getrusage(RUSAGE_SELF, &usage) == 0 && sent > 0)
        m["cpu_ms_per_frame"] = (1e3 * (usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                                 1e-3 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec)) /
                                static_cast<double>(sent);
    ctx.info("sent " + std::to_string(sent) + " frames");
}

}  // namespace

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-node";
    spec.usage = "rgbd-node --sensor KIND:ARG --hub ENDPOINT [options]";
    spec.description =
        "Streams one sensor to the capture hub (rgbd-capture): depth compressed losslessly "
        "with RVL, colour as JPEG, over ZeroMQ. A second socket (the hub endpoint's port + 1 "
        "unless --control is given) answers the hub's clock probes. The node waits for the "
        "hub's start (sent once the hub knows the node's clock), then streams until the "
        "sensor ends, --frames or --duration-s is reached, or SIGINT/SIGTERM. Sensors: "
        "playback:FOLDER[#ID] (a capture folder or TUM sequence replayed in real time; "
        "FOLDER/ID also names a sensor), synthetic:[ID] (an analytic Kinect v2 like scene)"
#ifdef RGBD_WITH_OPENNI2
        ", openni2:[URI] (an OpenNI2 device)"
#endif
        ".";
    spec.example = "rgbd-node --sensor playback:cap#k2-3 --loop --hub tcp://hub:5555 --key rig.key";
    spec.reads_stream = false;
    spec.writes_stream = false;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("sensor", cli::po::value<std::string>()->value_name("KIND:ARG"),
                        "the sensor (required): playback:FOLDER[#ID], synthetic:[ID]")(
            "hub", cli::value<std::string>("tcp://127.0.0.1:5555", "ENDPOINT"),
            "the hub's frame endpoint")(
            "control", cli::po::value<std::string>()->value_name("ENDPOINT"),
            "the hub's control endpoint (default: the hub endpoint's port + 1)")(
            "frames", cli::value<std::int64_t>(0, "N"),
            "stop after N frames (0 = until the sensor ends)")(
            "duration-s", cli::value<double>(0.0, "S"),
            "stop after S seconds of streaming (0 = no limit)")(
            "loop", "playback: start the recording again at its end")(
            "views",
            "prepare for making views (rgbd-capture --video --fuse-on nodes): playback decodes "
            "its colour once when opening; the hub's start message decides what is sent")(
            "cache-views",
            "benchmarks: with --views and a playback, make the view of every recording position "
            "before the start and send it again on every loop")(
            "no-align",
            "playback: do not put frame instants on the shared monotonic-clock grid (see "
            "sensors/playback/playback_sensor.hpp)")("no-color", "send depth only")(
            "jpeg-quality", cli::value<int>(90, "Q"),
            "JPEG quality for sensors that deliver raw colour (JPEG recordings are sent as is)")(
            "clock-offset-ms", cli::value<double>(0.0, "MS"),
            "testing: run the node's clock this far ahead of the machine's")(
            "clock-drift-ppm", cli::value<double>(0.0, "PPM"),
            "testing: run the node's clock fast by this many parts per million")(
            "work-delay-ms", cli::value<double>(0.0, "MS"),
            "testing: spend MS more on every frame before sending it (a node too slow for its "
            "sensor: it falls behind, and the hub says so)")(
            "truth", cli::po::value<std::string>()->value_name("FILE"),
            "testing: write session,index,source_position,true_ns,node_ns per frame sent")(
            "key", cli::po::value<std::string>()->value_name("FILE"),
            "CURVE key file (rgbd-capture --make-key): encrypt and authenticate")(
            "start-timeout-s", cli::value<double>(30.0, "S"),
            "give up when the hub does not answer within S seconds (0 = wait forever)")(
            "send-timeout-s", cli::value<double>(30.0, "S"),
            "give up when the hub accepts no frame for S seconds");
    };
    return cli::run_tool(argc, argv, spec, cli::zmq_errors_as_io_errors(run_node));
}
