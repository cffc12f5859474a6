// rgbd-capture: the capture hub (docs/algorithms.md §1, docs/algorithms.md §1). Receives frames
// from many rgbd-node processes over ZeroMQ, estimates each node's clock offset and drift with
// four-timestamp probes on a separate control socket, maps every frame to hub time, groups
// frames of all sensors into frame sets within a tolerance and records a capture folder v1
// (atomic files, csv appended line by line) that io::open_capture and rgbd-cloud read back.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <zmq.hpp>

#include "cli/capture_control.hpp"
#include "cli/capture_live.hpp"
#include "cli/capture_recorder.hpp"
#include "cli/capture_video.hpp"
#include "cli/common/tool.hpp"
#include "cli/hub_health.hpp"
#include "cli/node_views.hpp"
#include "cli/view_server.hpp"
#include "cli/zmq_errors.hpp"
#include "io/capture_folder.hpp"
#include "io/rvl.hpp"
#include "sensors/network/clock_sync.hpp"
#include "sensors/network/frame_grouper.hpp"
#include "sensors/network/protocol.hpp"
#include "sensors/network/transport.hpp"
#include "sensors/sensor.hpp"
#include "toolkit/error.hpp"

using namespace rgbd;
namespace net = rgbd::sensors::net;
namespace fs = std::filesystem;
using sensors::monotonic_ns;

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

using namespace cli::hub;

// ---------------------------------------------------------------------------------- hub

struct SensorStats {
    std::int64_t recorded = 0;
    std::int64_t last_hub_ns = std::numeric_limits<std::int64_t>::min();
    std::uint64_t session = 0;
    double period_ns = 1e9 / 30;
    std::vector<std::pair<std::int64_t, std::int64_t>> gaps;
};

void run_capture(cli::Context& ctx) {
    if (ctx.has("make-key")) {
        const std::string path = ctx.get<std::string>("make-key");
        if (fs::exists(path)) throw IoError(path + ": exists; refusing to overwrite a key file");
        net::write_key_file(path);
        ctx.note("wrote CURVE keys to " + path + " (give it to the hub and its nodes only)");
        return;
    }
    if (!ctx.inputs().empty())
        throw cli::UsageError("unexpected argument '" + ctx.inputs().front() + "'");
    if (!ctx.has("rig")) throw cli::UsageError("--rig FILE is required");
    const bool live = ctx.has("live");
    const bool video = ctx.has("video");
    if (ctx.output_path().empty() && !live && !video)
        throw cli::UsageError(
            "-o FOLDER is required (or --live to stream views, or --video DIR for a 3D video)");
    cli::VideoOptions video_options;
    cli::ViewServerOptions serve_options;
    if (video) {
        video_options.dir = ctx.get<std::string>("video");
        const std::string placement = ctx.get<std::string>("fuse-on");
        if (placement != "nodes" && placement != "hub")
            throw cli::UsageError("--fuse-on must be nodes or hub");
        video_options.fuse_on_nodes = placement == "nodes";
        if (video_options.fuse_on_nodes && (live || !ctx.output_path().empty()))
            throw cli::UsageError(
                "--fuse-on nodes: the nodes send views, not frames; -o and --live need "
                "--fuse-on hub");
        if (!ctx.output_path().empty() && fs::path(video_options.dir).lexically_normal() ==
                                              fs::path(ctx.output_path()).lexically_normal())
            throw cli::UsageError("--video and -o name the same folder");
        video_options.fusion.voxel_m = ctx.get<double>("voxel-mm") * 1e-3;
        video_options.fusion.extraction.crop_radius_m = ctx.get<double>("crop-radius-m");
        video_options.fusion.clean = !ctx.has("no-clean");
        video_options.draco.position_quantum_m = ctx.get<double>("draco-quantum-mm") * 1e-3;
        video_options.draco.color_bits = ctx.get<int>("draco-color-bits");
        video_options.draco.speed = ctx.get<int>("draco-speed");
        try {
            video_options.fusion.check();
            video_options.draco.check();
        } catch (const InputError& e) {
            throw cli::UsageError(e.what());
        }
    } else if (ctx.has("serve")) {
        throw cli::UsageError("--serve needs --video");
    }
    if (ctx.has("serve")) {
        serve_options.port = ctx.get<int>("serve");
        serve_options.bind = ctx.get<std::string>("bind");
        if (serve_options.port < 0 || serve_options.port > 65535)
            throw cli::UsageError("--serve must be a port 0..65535");
    }
    cli::LiveOptions live_options;
    if (live) {
        live_options.path = ctx.get<std::string>("live");
        live_options.max_sets = ctx.get<long long>("live-sets");
        if (live_options.max_sets < 0) throw cli::UsageError("--live-sets must be >= 0");
        if (live_options.path.empty()) throw cli::UsageError("--live needs a file, a FIFO or -");
        if (live_options.path == "-" && ctx.has("metrics") &&
            ctx.get<std::string>("metrics") == "-")
            throw cli::UsageError("--live - and --metrics - both want stdout");
        if (!ctx.output_path().empty() && live_options.path != "-" &&
            fs::path(live_options.path).lexically_normal() ==
                fs::path(ctx.output_path()).lexically_normal())
            throw cli::UsageError("--live and -o name the same path");
    } else if (ctx.has("live-sets")) {
        throw cli::UsageError("--live-sets needs --live");
    }
    const double tolerance_ms = ctx.get<double>("tolerance-ms");
    const double latency_ms = ctx.get<double>("latency-ms");
    const double duration_s = ctx.get<double>("duration-s");
    HubOptions options;
    options.probes = ctx.get<int>("probes");
    const double interval_ms = ctx.get<double>("probe-interval-ms");
    options.drift_window_s = ctx.get<double>("drift-window-s");
    const double start_wait_s = ctx.get<double>("start-wait-s");
    if (!(start_wait_s >= 0 && start_wait_s <= 3600))
        throw cli::UsageError("--start-wait-s must be in [0, 3600]");
    options.start_wait_ns = static_cast<std::int64_t>(start_wait_s * 1e9);
    const double start_lead_ms = ctx.get<double>("start-lead-ms");
    if (!(start_lead_ms >= 10 && start_lead_ms <= 600000))
        throw cli::UsageError("--start-lead-ms must be in [10, 600000]");
    options.start_lead_ns = static_cast<std::int64_t>(start_lead_ms * 1e6);
    const int png = ctx.get<int>("png-compression");
    if (!(tolerance_ms >= 0 && tolerance_ms <= 1000))
        throw cli::UsageError("--tolerance-ms must be in [0, 1000]");
    if (!(latency_ms >= 0 && latency_ms <= 60000))
        throw cli::UsageError("--latency-ms must be in [0, 60000]");
    if (!(duration_s >= 0)) throw cli::UsageError("--duration-s must be >= 0");
    if (options.probes < 1 || options.probes > 1000)
        throw cli::UsageError("--probes must be in [1, 1000]");
    if (!(interval_ms >= 10 && interval_ms <= 3.6e6))
        throw cli::UsageError("--probe-interval-ms must be in [10, 3.6e6]");
    if (!(options.drift_window_s >= 1)) throw cli::UsageError("--drift-window-s must be >= 1");
    if (png < 0 || png > 9) throw cli::UsageError("--png-compression must be 0..9");
    options.probe_interval_ns = static_cast<std::int64_t>(interval_ms * 1e6);

    io::Rig rig = io::read_rig(ctx.get<std::string>("rig"));
    for (io::SensorSpec& s : rig.sensors) {
        if (s.id.size() > net::kMaxSensorId)
            throw InputError(ctx.get<std::string>("rig") + ": sensor id '" + s.id +
                             "' is too long for the network (max " +
                             std::to_string(net::kMaxSensorId) + ")");
        s.clock_offset_ns = 0;  // the hub records in its own time
        s.extra.erase("clock");
    }
    std::unique_ptr<net::CurveKeys> keys;
    if (ctx.has("key")) {
        if (!net::curve_available())
            throw IoError("--key: this libzmq has no CURVE support (zmq_has(\"curve\") is 0)");
        keys = std::make_unique<net::CurveKeys>(net::read_key_file(ctx.get<std::string>("key")));
    }
    if (video && video_options.fuse_on_nodes) {
        // The start message asks every node for views of its sensor at the rig pose.
        const std::optional<Eigen::Vector3d> centre = pipeline::object_centre(rig);
        options.start_json = [&rig, centre, &video_options](std::size_t sensor) {
            cli::ViewRequest request;
            request.world_from_sensor = rig.sensors[sensor].world_from_depth;
            request.centre = centre;
            request.crop_radius_m = video_options.fusion.extraction.crop_radius_m;
            request.clean = video_options.fusion.clean;
            return cli::view_request_to_json(request).dump();
        };
    }
    const std::string listen = ctx.get<std::string>("listen");
    const std::string control =
        ctx.has("control") ? ctx.get<std::string>("control") : net::control_endpoint_for(listen);

    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    if (live) std::signal(SIGPIPE, SIG_IGN);  // a reader that goes away must not kill the hub

    zmq::context_t context(1);
    std::unique_ptr<net::ZapAuthenticator> zap;
    if (keys) zap = std::make_unique<net::ZapAuthenticator>(context, keys->client_public);
    zmq::socket_t pull(context, zmq::socket_type::pull);
    pull.set(zmq::sockopt::rcvhwm, 4000);
    pull.set(zmq::sockopt::linger, 0);
    pull.set(zmq::sockopt::maxmsgsize, static_cast<std::int64_t>(2 * net::kMaxPayload + 4096));
    if (keys) net::make_curve_server(pull, *keys);
    cli::listen_on(pull, "--listen", listen);
    ControlHub hub(context, control, rig, options, keys.get(), ctx);
    // The output folder is created only once the sockets are up (no empty folders on error).
    Recorder recorder(ctx.output_path(), rig, png);
    ctx.info("listening on " + listen + " (control " + control + ")" +
             (recorder.recording() ? ", recording to " + ctx.output_path() : std::string()) +
             (live ? ", live views to " + live_options.path : std::string()));

    const std::size_t n = rig.sensors.size();
    const auto tolerance_ns = static_cast<std::int64_t>(std::llround(tolerance_ms * 1e6));
    const auto latency_ns = static_cast<std::int64_t>(std::llround(latency_ms * 1e6));
    net::FrameGrouper grouper(n, tolerance_ns, /*complete_early=*/video);
    // Live stream: frames are kept as long as a set can still be formed from them.
    std::unique_ptr<cli::FrameHistory> history;
    std::unique_ptr<cli::LiveStream> stream;
    std::unique_ptr<cli::ViewServer> server;
    std::unique_ptr<cli::VideoStream> fusion;
    std::int64_t sets_formed = 0;
    if (live || video)
        history =
            std::make_unique<cli::FrameHistory>(n, latency_ns + 4 * tolerance_ns + 500'000'000);
    if (video) {
        if (ctx.has("serve")) {
            server = std::make_unique<cli::ViewServer>(serve_options, std::nullopt);
            ctx.info("live 3D video at http://" + serve_options.bind + ":" +
                     std::to_string(server->port()) + "/");
        }
        cli::ViewServer* page = server.get();
        fusion = std::make_unique<cli::VideoStream>(
            rig, video_options, ctx, [page](const cli::FusedFrame& f) {
                if (page) page->publish(f.frame, f.info, f.points);
            });
    }
    if (live) {
        stream = std::make_unique<cli::LiveStream>(
            rig, live_options, ctx,
            [&recorder](std::int64_t ordinal) {
                if (!recorder.recording() || recorder.failed()) return -1;
                return recorder.sets_written() > ordinal ? 1 : 0;
            },
            [&recorder](const std::string& sensor, std::int64_t index) {
                return recorder.depth_file(sensor, index);
            });
    }
    std::vector<SensorStats> stats(n);
    std::vector<io::FrameSet> sets;
    std::map<std::string, std::int64_t> dropped;  // reason -> count
    std::int64_t received = 0, unsynchronised = 0, complete_sets = 0, missing_slots = 0;
    std::int64_t max_spread = 0;
    const std::int64_t start = monotonic_ns();
    const bool exit_after_bye = ctx.has("exit-after-bye");
    net::FrameView view;
    std::string error;
    zmq::message_t message;
    io::ColoredPoints view_points;
    // Why views are late or sets skipped, said once per cause (cli/hub_health.hpp).
    cli::HealthOptions health_options;
    health_options.frame_period_ms = 1000.0 / video_options.frame_rate_hz;
    health_options.deadline_ms = latency_ms;
    health_options.repeat_s = ctx.get<double>("health-repeat-s");
    health_options.fuse_on_nodes = video_options.fuse_on_nodes;
    health_options.video = video;
    for (const io::SensorSpec& s : rig.sensors) health_options.sensor_ids.push_back(s.id);
    cli::HubHealth health(health_options);
    // One received frame or view: grouped, and its timing given to the health check.
    const auto arrived = [&](std::size_t sensor, const net::ClockFit& fit, std::int64_t hub_ns,
                             std::int64_t index) {
        const bool on_time = grouper.add(sensor, hub_ns, index);
        const std::int64_t sent =
            view.header.sent_ns != 0 ? fit.to_hub(view.header.sent_ns) : cli::HubHealth::kUnknown;
        health.frame(sensor, hub_ns, sent, monotonic_ns(), !on_time);
    };
    const auto check_health = [&](std::int64_t now) {
        if (fusion) {
            std::int64_t offered = 0, fused = 0, skipped = 0;
            double wall_ms = 0, cpu_ms = 0;
            fusion->totals(offered, fused, skipped, wall_ms, cpu_ms);
            health.fusion_totals(offered, fused, skipped, wall_ms, cpu_ms);
        }
        for (const std::string& line : health.tick(now, cli::sample_system())) ctx.warn(line);
    };

    const auto drop = [&](const std::string& reason) {
        ++dropped[reason];
        if (dropped[reason] == 1) ctx.warn("dropped a message: " + reason);
    };
    const auto handle = [&](const zmq::message_t& msg) {
        const auto* data = static_cast<const std::uint8_t*>(msg.data());
        if (!net::parse_frame(data, msg.size(), view, error)) return drop(error);
        net::ClockFit fit;
        std::size_t sensor = 0;
        if (!hub.lookup(view.header.session, fit, sensor)) {
            ++unsynchronised;
            return drop("frame from a session without a clock estimate");
        }
        const io::SensorSpec& spec = rig.sensors[sensor];
        if (view.header.sensor_id != spec.id) return drop("sensor id differs from the hello");
        if (view.header.width != spec.depth.width || view.header.height != spec.depth.height)
            return drop("depth size differs from the rig");
        if (view.header.kind == net::PayloadKind::kView) {
            // A node's fused-ready view (--fuse-on nodes): no recording, straight to the video.
            if (!fusion || !video_options.fuse_on_nodes)
                return drop("a view, but this hub asked for frames");
            if (!cli::decode_view_payload(view.depth, view.header.depth_bytes, view.color,
                                          view.header.color_bytes, view_points, error))
                return drop(error);
            SensorStats& st = stats[sensor];
            const std::int64_t hub_ns = fit.to_hub(view.header.node_ns);
            if (st.last_hub_ns != std::numeric_limits<std::int64_t>::min() &&
                hub_ns - st.last_hub_ns > 1.5 * st.period_ns)
                st.gaps.emplace_back(st.last_hub_ns, hub_ns);
            st.last_hub_ns = std::max(st.last_hub_ns, hub_ns);
            const std::int64_t index = st.recorded++;
            arrived(sensor, fit, hub_ns, index);
            history->store_view(sensor, index, hub_ns, view_points);
            ++received;
            return;
        }
        auto job = recorder.take();
        job->depth.create(spec.depth.height, spec.depth.width, CV_16UC1);
        try {
            io::rvl_decompress(view.depth, view.header.depth_bytes, job->depth.ptr<std::uint16_t>(),
                               job->depth.total(), "frame message");
        } catch (const InputError& e) {
            recorder.push_back_free(std::move(job));
            return drop("corrupt RVL depth");
        }
        job->jpeg.assign(view.color, view.color + view.header.color_bytes);
        SensorStats& st = stats[sensor];
        const std::int64_t hub_ns = fit.to_hub(view.header.node_ns);
        if (st.session != view.header.session) {
            st.session = view.header.session;
        }
        if (st.last_hub_ns != std::numeric_limits<std::int64_t>::min() &&
            hub_ns - st.last_hub_ns > 1.5 * st.period_ns)
            st.gaps.emplace_back(st.last_hub_ns, hub_ns);
        st.last_hub_ns = std::max(st.last_hub_ns, hub_ns);
        job->is_set = false;
        job->sensor = sensor;
        job->index = st.recorded++;
        job->hub_ns = hub_ns;
        arrived(sensor, fit, hub_ns, job->index);
        if (history)
            history->store(sensor, job->index, hub_ns, job->depth, view.color,
                           view.header.color_bytes);
        recorder.push(std::move(job));
        ++received;
    };
    const auto form_sets = [&](std::int64_t horizon) {
        sets.clear();
        grouper.form(horizon, sets);
        for (io::FrameSet& set : sets) {
            const auto missing = std::count(set.frames.begin(), set.frames.end(), -1);
            missing_slots += missing;
            complete_sets += missing == 0;
            max_spread = std::max(max_spread, set.spread_ns);
            auto job = recorder.take();
            job->is_set = true;
            job->set = set;
            recorder.push(std::move(job));
            if (stream) stream->offer(set, sets_formed, *history);
            if (fusion) fusion->offer(set, *history);
            ++sets_formed;
        }
    };

    std::string stop_reason = "signal";
    std::int64_t last_formed = monotonic_ns();
    std::int64_t last_health = 0;
    for (;;) {
        if (g_stop) break;
        if (monotonic_ns() - last_health > 250'000'000) {
            last_health = monotonic_ns();
            check_health(last_health);
        }
        if (recorder.failed()) break;
        if (fusion && fusion->failed()) break;
        if (duration_s > 0 &&
            monotonic_ns() - start > static_cast<std::int64_t>(duration_s * 1e9)) {
            stop_reason = "duration";
            break;
        }
        if (exit_after_bye && hub.all_done()) {
            stop_reason = "all nodes done";
            break;
        }
        if (stream && stream->finished() && !(stream->reader_closed() && recorder.recording())) {
            stop_reason = stream->reader_closed() ? "live reader closed" : "live sets streamed";
            break;
        }
        zmq::pollitem_t item{pull.handle(), 0, ZMQ_POLLIN, 0};
        if (!poll_once(item)) continue;
        int taken = 0;
        for (; taken < 64 && pull.recv(message, zmq::recv_flags::dontwait); ++taken) {
            if (message.more()) {
                while (message.more() && pull.recv(message, zmq::recv_flags::none)) {
                }
                drop("multi-part message");
                continue;
            }
            handle(message);
        }
        // Sets are formed once the socket is drained: a hub that falls behind (a loaded
        // machine) reads the frames waiting for it before it closes their windows, so they are
        // not late. It still forms them at least every latency / 2 when it never drains.
        const std::int64_t now = monotonic_ns();
        if (taken < 64 || now - last_formed > latency_ns / 2) {
            form_sets(now - latency_ns);
            last_formed = now;
        }
    }
    if (!recorder.failed()) {
        // Drain: what the nodes already sent, until the socket is quiet for 300 ms.
        std::int64_t quiet_since = monotonic_ns();
        const std::int64_t drain_start = quiet_since;
        while (monotonic_ns() - quiet_since < 300'000'000 &&
               monotonic_ns() - drain_start < 10'000'000'000 && !recorder.failed()) {
            zmq::pollitem_t item{pull.handle(), 0, ZMQ_POLLIN, 0};
            if (!poll_once(item)) continue;
            while (pull.recv(message, zmq::recv_flags::dontwait)) {
                if (message.more()) {
                    while (message.more() && pull.recv(message, zmq::recv_flags::none)) {
                    }
                    drop("multi-part message");
                    continue;
                }
                handle(message);
                quiet_since = monotonic_ns();
            }
        }
        form_sets(std::numeric_limits<std::int64_t>::max());
    }
    const std::int64_t end = monotonic_ns();
    hub.stop();
    recorder.finish();
    if (stream) stream->finish();
    const std::string final_reason = recorder.failed()            ? "recording failed"
                                     : fusion && fusion->failed() ? "video write failed"
                                                                  : stop_reason;
    if (fusion) fusion->finish(final_reason);
    if (server) server->stop();
    const Report clocks = hub.report(end);

    auto& m = ctx.metrics();
    m["output"] = ctx.output_path();
    m["stop_reason"] = final_reason;
    m["duration_s"] = 1e-9 * static_cast<double>(end - start);
    // Peak resident memory of the hub process (getrusage; Linux reports KiB): a slow --live
    // reader must not make it grow (issue 21).
    rusage usage{};
    if (::getrusage(RUSAGE_SELF, &usage) == 0) {
        m["peak_rss_mb"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
        // CPU of the whole hub (user + system, every thread), for the video benchmark.
        m["cpu_s"] = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                     1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    }
    m["frames_received"] = received;
    m["frames_recorded"] = recorder.frames_written();
    m["framesets"] = recorder.recording() ? recorder.sets_written() : sets_formed;
    m["framesets_complete"] = complete_sets;
    m["missing_slots"] = missing_slots;
    m["max_spread_ns"] = max_spread;
    m["late_frames"] = grouper.late();
    m["tolerance_ns"] = tolerance_ns;
    std::int64_t dropped_total = 0;
    for (const auto& [reason, count] : dropped) dropped_total += count;
    m["dropped_messages"] = dropped_total;
    m["dropped_by_reason"] = dropped;
    m["malformed_control_messages"] = hub.malformed();
    m["refused_nodes"] = hub.refused();
    if (zap) m["refused_connections"] = zap->refused();
    Report per_sensor = Report::object();
    for (std::size_t s = 0; s < n; ++s) {
        Report r = {{"frames", stats[s].recorded}, {"gaps", Report::array()}};
        for (const auto& [a, b] : stats[s].gaps) r["gaps"].push_back({a, b});
        if (clocks.contains(rig.sensors[s].id)) r["clock"] = clocks[rig.sensors[s].id];
        per_sensor[rig.sensors[s].id] = r;
    }
    m["sensors"] = per_sensor;
    m["health"] = health.report();
    {
        const Report& h = m["health"];
        const Report& c = h["causes"];
        if (h["views_late"].get<std::int64_t>() > 0 ||
            c["fusion_slow"]["sets_skipped"].get<std::int64_t>() > 0)
            ctx.note("late: " + h["views_late"].dump() + " of " + h["views"].dump() +
                     " views (nodes behind " + c["nodes_behind"]["views_late"].dump() +
                     ", hub behind " + c["hub_behind"]["views_late"].dump() + "), " +
                     c["fusion_slow"]["sets_skipped"].dump() +
                     " frame sets skipped (fusion slower than the frames); " +
                     std::to_string(c["nodes_behind"]["warnings"].get<int>() +
                                    c["hub_behind"]["warnings"].get<int>() +
                                    c["fusion_slow"]["warnings"].get<int>()) +
                     " warnings on why");
    }
    if (stream) {
        m["live"] = stream->metrics();
        m["live"]["output"] = live_options.path;
        const Report& l = m["live"];
        ctx.note("live: " + l["sets_emitted"].dump() + " frame sets streamed (" +
                 l["views"].dump() + " views), " + l["sets_skipped"].dump() +
                 " skipped for newer ones, " + l["sets_incomplete"].dump() + " incomplete");
    }

    if (fusion) {
        m["video"] = fusion->metrics();
        m["video"]["dir"] = video_options.dir;
        m["video"]["placement"] = video_options.fuse_on_nodes ? "nodes" : "hub";
        const Report& v = m["video"];
        ctx.note("video: " + v["sets_fused"].dump() + " fused frame sets in " + video_options.dir +
                 " (" + v["sets_skipped"].dump() + " skipped for newer ones, " +
                 v["sets_thinned"].dump() + " thinned, " + v["sets_empty"].dump() + " empty)");
        if (fusion->failed())
            throw IoError("video stopped: " + fusion->error() + "; " + video_options.dir +
                          " holds " + v["sets_fused"].dump() + " frames, all readable");
    }
    if (recorder.failed())
        throw IoError("recording stopped: " + recorder.error() + "; " + recorder.root().string() +
                      " holds " + std::to_string(recorder.frames_written()) + " frames and " +
                      std::to_string(recorder.sets_written()) +
                      " frame sets, all complete and readable");
    if (!recorder.recording()) return;
    // rig.json again, now with each node's clock estimate (times in the capture are hub time).
    for (io::SensorSpec& s : rig.sensors)
        if (clocks.contains(s.id))
            s.extra["clock"] = {{"node_offset_ns", clocks[s.id]["offset_ns"]},
                                {"node_drift_ppm", clocks[s.id]["drift_ppm"]},
                                {"at_hub_ns", end}};
    io::write_rig(recorder.root() / "rig.json", rig);
    ctx.note("recorded " + std::to_string(recorder.frames_written()) + " frames in " +
             std::to_string(recorder.sets_written()) + " frame sets (" +
             std::to_string(complete_sets) + " complete), " + std::to_string(dropped_total) +
             " messages dropped");
}

}  // namespace

int main(int argc, char** argv) {
    cli::ToolSpec spec;
    spec.name = "rgbd-capture";
    spec.usage =
        "rgbd-capture --rig rig.json [--listen ENDPOINT] (-o FOLDER | --live FILE|-) [options]";
    spec.description =
        "The capture hub. Receives frames from rgbd-node processes over ZeroMQ (PULL on "
        "--listen), estimates every node's clock offset and drift with four-timestamp probes "
        "on the control socket (--listen's port + 1 unless --control is given; bursts of "
        "--probes probes, the least-queued of each burst kept, a least-squares drift fit over "
        "--drift-window-s), maps frame time stamps to hub time, groups frames into frame sets "
        "(each set's spread <= --tolerance-ms; a sensor without a frame in the window is "
        "missing) and records a capture folder v1: images written atomically, frames.csv and "
        "framesets.csv appended line by line, times in hub time, each node's clock estimate "
        "in rig.json. Malformed or truncated messages are counted and dropped. Stops on "
        "SIGINT/SIGTERM, after --duration-s, or with --exit-after-bye when every node has "
        "finished; on a full disk it stops with what was recorded intact (exit 1). With "
        "--key the sockets are CURVE-encrypted and only nodes holding the key file are "
        "accepted.\n\n"
        "Live pipeline: with --live the newest complete frame sets also go out as a view "
        "stream (one coloured cloud per sensor, in the sensor frame with its rig pose, the same "
        "views rgbd-cloud makes from the recording); --live-sets 1 takes one snapshot and "
        "stops, e.g. rgbd-capture --rig rig.json --live - --live-sets 1 | rgbd-clean | "
        "rgbd-align | rgbd-mesh -o bust.ply.";
    spec.example =
        "rgbd-capture --rig rig.json --listen tcp://*:5555 -o cap/ --key rig.key "
        "--metrics hub.json";
    spec.reads_stream = false;
    spec.writes_stream = false;
    spec.add_options = [](cli::po::options_description& o) {
        o.add_options()("rig", cli::po::value<std::string>()->value_name("FILE"),
                        "rig.json of the sensors to record (required)")(
            "listen", cli::value<std::string>("tcp://*:5555", "ENDPOINT"),
            "frame endpoint to listen on")("control",
                                           cli::po::value<std::string>()->value_name("ENDPOINT"),
                                           "control endpoint (default: --listen's port + 1)")(
            "tolerance-ms", cli::value<double>(16.7, "MS"),
            "largest spread of a frame set (hub time)")(
            "latency-ms", cli::value<double>(1000.0, "MS"),
            "wait this long for late frames before forming a set")(
            "probes", cli::value<int>(HubOptions{}.probes, "N"), "clock probes per burst")(
            "probe-interval-ms", cli::value<double>(HubOptions{}.probe_interval_ns / 1e6, "MS"),
            "time between probe bursts per node")(
            "drift-window-s", cli::value<double>(HubOptions{}.drift_window_s, "S"),
            "fit offset and drift over this many seconds of bursts")(
            "duration-s", cli::value<double>(0.0, "S"),
            "stop after S seconds (0 = until a signal)")(
            "exit-after-bye", "stop when every node that joined has finished")(
            "start-lead-ms", cli::value<double>(HubOptions{}.start_lead_ns / 1e6, "MS"),
            "the common start instant lies this far ahead of the moment it is fixed")(
            "start-wait-s", cli::value<double>(HubOptions{}.start_wait_ns / 1e9, "S"),
            "every rig node starts on one common instant once all have joined; after this "
            "long the ones that joined start without the others (latecomers join the frame "
            "grid)")("png-compression", cli::value<int>(1, "LEVEL"),
                     "zlib level of the recorded depth PNGs (0-9; lossless at every level)")(
            "key", cli::po::value<std::string>()->value_name("FILE"),
            "CURVE key file: encrypt, and refuse nodes without the key")(
            "make-key", cli::po::value<std::string>()->value_name("FILE"),
            "write a new CURVE key file and exit")(
            "live", cli::po::value<std::string>()->value_name("FILE"),
            "also stream the newest complete frame sets as views (a view stream, as rgbd-cloud "
            "makes from the recording) to FILE, a FIFO or - (stdout); a slow reader gets the "
            "newest set each time, the sets in between are skipped. Without -o nothing is "
            "recorded")("live-sets", cli::value<long long>(0, "N"),
                        "with --live: stop after streaming N frame sets (0 = no limit)")(
            "video", cli::po::value<std::string>()->value_name("DIR"),
            "fuse every frame set into one coloured point cloud while capturing and write a "
            "3D video folder (video.json + Draco frames); without -o nothing else is recorded")(
            "fuse-on", cli::value<std::string>("nodes", "WHERE"),
            "where the per-view work runs: nodes (they send cleaned world-frame views, as "
            "LiveScan3D's clients do) or hub (they send frames)")(
            "voxel-mm", cli::value<double>(cli::VideoOptions{}.fusion.voxel_m * 1000.0, "MM"),
            "voxel edge of the fused cloud (0 = the sensors' pixel footprint at the object)")(
            "crop-radius-m",
            cli::value<double>(cli::VideoOptions{}.fusion.extraction.crop_radius_m, "M"),
            "keep points within this distance of the rig's object centre (0 = no crop)")(
            "no-clean", "skip the per-view distance-based clean")(
            "draco-quantum-mm",
            cli::value<double>(cli::VideoOptions{}.draco.position_quantum_m * 1000.0, "MM"),
            "Draco position grid of the video frames")(
            "draco-color-bits", cli::value<int>(cli::VideoOptions{}.draco.color_bits, "BITS"),
            "colour bits per channel kept in the video frames (1-8)")(
            "draco-speed", cli::value<int>(cli::VideoOptions{}.draco.speed, "N"),
            "Draco encoding speed (0 = smallest, 10 = fastest)")(
            "serve", cli::po::value<int>()->value_name("PORT"),
            "with --video: serve the live fused stream as a web page on PORT")(
            "bind", cli::value<std::string>("127.0.0.1", "ADDRESS"),
            "address the --serve page listens on (another address lets remote viewers in)")(
            "health-repeat-s", cli::value<double>(cli::HealthOptions{}.repeat_s, "S"),
            "when views arrive too late or frame sets are skipped for more than 3 s, say why "
            "(nodes behind, hub behind, fusion slow) and what helps, once per cause every S s");
    };
    spec.ranges = {{"drift-window-s", Range::closed(1, 86400), "s"},
                   {"health-repeat-s", Range::closed(0.1, 86400), "s"},
                   {"duration-s", Range::closed(0, 1e7), "s"}};
    spec.scopes = {{{"video"},
                    {"fuse-on", "voxel-mm", "crop-radius-m", "no-clean", "draco-quantum-mm",
                     "draco-color-bits", "draco-speed"}},
                   {{"serve"}, {"bind"}}};
    return cli::run_tool(argc, argv, spec, cli::zmq_errors_as_io_errors(run_capture));
}
