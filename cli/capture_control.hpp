// rgbd-capture, the control side of the hub (docs/algorithms.md §1, docs/algorithms.md §1): the
// node sessions, their four-timestamp clock probes and the start/stop messages, on a thread of its
// own. Used only by cli/rgbd_capture.cpp.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <zmq.hpp>

#include "cli/capture_live.hpp"
#include "cli/common/tool.hpp"
#include "cli/zmq_errors.hpp"
#include "io/capture_folder.hpp"
#include "io/rvl.hpp"
#include "sensors/network/clock_sync.hpp"
#include "sensors/network/frame_grouper.hpp"
#include "sensors/network/protocol.hpp"
#include "sensors/network/transport.hpp"
#include "sensors/sensor.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli::hub {

namespace net = rgbd::sensors::net;
namespace fs = std::filesystem;
using sensors::monotonic_ns;

/// Polls for up to 20 ms; false when a signal interrupted the wait (EINTR).
inline bool poll_once(zmq::pollitem_t& item) {
    try {
        zmq::poll(&item, 1, std::chrono::milliseconds(20));
        return true;
    } catch (const zmq::error_t& e) {
        if (e.num() != EINTR) throw;
        return false;
    }
}

struct HubOptions {
    int probes = 16;
    std::int64_t probe_interval_ns = 1'000'000'000;
    double drift_window_s = 60;
    std::int64_t probe_timeout_ns = 500'000'000;
    /// Least time between two probes of a burst: a burst then spans about two frame periods,
    /// so that its least-queued probe falls between the nodes' frame bursts.
    std::int64_t probe_spacing_ns = 4'000'000;
    /// The common start instant lies this far after the moment the last node's clock is known
    /// (the start message must reach every node before it).
    std::int64_t start_lead_ns = 300'000'000;
    /// Start the nodes that are ready when not every rig sensor has joined this long after the
    /// first one was ready.
    std::int64_t start_wait_ns = 10'000'000'000;
    /// JSON of the start message to the node of rig sensor k (none, or empty: frames).
    std::function<std::string(std::size_t)> start_json;
};

// ---------------------------------------------------------------------------------- control

/// Probe bursts a node's clock gets before it may start.
inline constexpr std::size_t kBurstsBeforeStart = 3;

/// One node run (session): its clock estimate and the probe schedule.
struct Session {
    std::string routing_id;
    std::size_t sensor = 0;
    double rate_hz = 30;
    net::ClockEstimator clock;
    int burst_count = 0;       ///< probes of the current burst sent and answered/timed out
    std::uint32_t seq = 0;     ///< sequence number of the outstanding probe
    bool awaiting = false;     ///< a probe is outstanding
    std::int64_t sent_at = 0;  ///< hub time of the outstanding probe
    std::int64_t next_at = 0;  ///< hub time of the next probe
    int timeouts = 0;          ///< consecutive timeouts
    bool ready = false;        ///< the clock is known (first burst kept)
    bool started = false, bye = false;
    std::int64_t start_hub_ns = 0;       ///< its first frame's instant, hub time
    std::int64_t frames_announced = -1;  ///< from bye
};

/// Runs the control socket on its own thread, so probe replies are stamped as they arrive and
/// never wait behind frame processing.
class ControlHub {
public:
    ControlHub(zmq::context_t& context, const std::string& endpoint, const io::Rig& rig,
               const HubOptions& options, const net::CurveKeys* keys, cli::Context& ctx)
        : socket_(context, zmq::socket_type::router), rig_(rig), options_(options), ctx_(ctx) {
        socket_.set(zmq::sockopt::linger, 0);
        socket_.set(zmq::sockopt::router_mandatory, 0);
        if (keys) net::make_curve_server(socket_, *keys);
        listen_on(socket_, "--control", endpoint);
        thread_ = std::thread([this] { run(); });
    }
    ~ControlHub() { stop(); }
    void stop() {
        stop_ = true;
        if (thread_.joinable()) thread_.join();
    }

    /// The clock fit and sensor of a session that has been started; false otherwise.
    bool lookup(std::uint64_t session, net::ClockFit& fit, std::size_t& sensor) {
        std::lock_guard<std::mutex> lock(mutex_);
        const auto it = sessions_.find(session);
        if (it == sessions_.end() || !it->second.started) return false;
        fit = it->second.clock.fit();
        sensor = it->second.sensor;
        return true;
    }
    /// Every sensor that said hello has said bye in its latest session.
    bool all_done() {
        std::lock_guard<std::mutex> lock(mutex_);
        if (latest_.empty()) return false;
        for (const auto& [sensor, session] : latest_)
            if (!sessions_.at(session).bye) return false;
        return true;
    }
    std::int64_t malformed() const { return malformed_; }
    /// The rig's common start instant (hub time), 0 before it is fixed.
    std::int64_t common_start_ns() {
        std::lock_guard<std::mutex> lock(mutex_);
        return common_start_ns_;
    }
    std::int64_t refused() const { return refused_; }

    /// Per sensor: clock estimate at hub time `at`, sessions, probes.
    Report report(std::int64_t at) {
        std::lock_guard<std::mutex> lock(mutex_);
        Report r = Report::object();
        for (const auto& [sensor, session] : latest_) {
            const Session& s = sessions_.at(session);
            int count = 0;
            for (const auto& [id, other] : sessions_) count += other.sensor == sensor;
            r[rig_.sensors[sensor].id] = {{"offset_ns", s.clock.offset_ns_at(at)},
                                          {"drift_ppm", s.clock.drift_ppm()},
                                          {"at_hub_ns", at},
                                          {"bursts", s.clock.bursts()},
                                          {"last_round_trip_ns", s.clock.last_round_trip_ns()},
                                          {"max_round_trip_ns", s.clock.max_round_trip_ns()},
                                          {"sessions", count},
                                          {"session", session},
                                          {"start_hub_ns", s.start_hub_ns},
                                          {"bye", s.bye}};
        }
        return r;
    }

private:
    void send(const std::string& routing_id, const net::ControlMessage& m) {
        const auto bytes = net::encode_control(m);
        try {
            socket_.send(zmq::buffer(routing_id),
                         zmq::send_flags::sndmore | zmq::send_flags::dontwait);
            socket_.send(zmq::buffer(bytes), zmq::send_flags::dontwait);
        } catch (const zmq::error_t&) {
        }
    }

    void on_message(const std::string& routing_id, const std::uint8_t* data, std::size_t size,
                    std::int64_t t3) {
        net::ControlMessage m;
        std::string error;
        if (!net::parse_control(data, size, m, error)) {
            ++malformed_;
            return;
        }
        std::lock_guard<std::mutex> lock(mutex_);
        if (m.type == net::ControlType::kHello) {
            if (sessions_.count(m.session)) {
                Session& s = sessions_.at(m.session);
                s.routing_id = routing_id;
                if (s.started) send_start(s);
                return;
            }
            nlohmann::json hello = nlohmann::json::parse(m.json, nullptr, false);
            const std::string id =
                hello.is_object() && hello.contains("sensor") && hello["sensor"].is_string()
                    ? hello["sensor"].get<std::string>()
                    : std::string();
            std::size_t sensor = 0;
            while (sensor < rig_.sensors.size() && rig_.sensors[sensor].id != id) ++sensor;
            if (sensor == rig_.sensors.size()) {
                ++refused_;
                ctx_.warn("refused a node: sensor '" + id + "' is not in the rig");
                return;
            }
            const io::SensorSpec& spec = rig_.sensors[sensor];
            if (hello.value("width", 0) != spec.depth.width ||
                hello.value("height", 0) != spec.depth.height) {
                ++refused_;
                ctx_.warn("refused sensor '" + id + "': depth size differs from the rig");
                return;
            }
            Session s{.routing_id = routing_id,
                      .sensor = sensor,
                      .rate_hz = hello.value("rate_hz", 30.0),
                      .clock = net::ClockEstimator(options_.drift_window_s)};
            s.next_at = t3;
            sessions_.emplace(m.session, std::move(s));
            latest_[sensor] = m.session;
            ctx_.info("sensor '" + id + "' joined (session " + std::to_string(m.session) + ")");
            return;
        }
        if (m.type == net::ControlType::kBye) {
            const auto it = sessions_.find(m.session);
            if (it != sessions_.end()) {
                it->second.bye = true;
                it->second.frames_announced = m.frames;
            }
            return;
        }
        if (m.type == net::ControlType::kProbeReply) {
            for (auto& [id, s] : sessions_) {
                if (s.routing_id != routing_id || !s.awaiting || m.seq != s.seq) continue;
                s.awaiting = false;
                s.timeouts = 0;
                s.clock.add_probe({m.t0, m.t1, m.t2, t3});
                finish_probe(s, t3);
                return;
            }
            return;  // a late reply to a timed-out probe
        }
        ++malformed_;  // probes and starts are not for the hub
    }

    void finish_probe(Session& s, std::int64_t now) {
        if (++s.burst_count < options_.probes) {
            s.next_at = std::max(now, s.sent_at + options_.probe_spacing_ns);
            return;
        }
        s.burst_count = 0;
        s.clock.end_burst();
        s.next_at = now + options_.probe_interval_ns;
        // Before its start a node gets kBurstsBeforeStart bursts back to back: the first frames
        // are mapped through a fit of several bursts (weighted by round trip), not through one
        // burst that may have met a busy moment.
        if (!s.ready && s.clock.bursts() >= kBurstsBeforeStart) {
            s.ready = true;
            if (first_ready_ns_ == 0) first_ready_ns_ = now;
        } else if (!s.ready) {
            s.next_at = now;
        }
    }

    /// Start message of a started session: its instant in the node's clock.
    void send_start(const Session& s) {
        net::ControlMessage m;
        m.type = net::ControlType::kStart;
        m.t0 = s.start_hub_ns +
               static_cast<std::int64_t>(std::llround(s.clock.offset_ns_at(s.start_hub_ns)));
        m.t1 = period_ns(s);
        if (options_.start_json) m.json = options_.start_json(s.sensor);
        send(s.routing_id, m);
    }
    static std::int64_t period_ns(const Session& s) {
        return static_cast<std::int64_t>(
            std::llround(1e9 / (s.rate_hz > 0 && s.rate_hz <= 1000 ? s.rate_hz : 30.0)));
    }

    /// The common start (docs/algorithms.md §1): once every rig sensor's latest session has
    /// a clock (or start_wait_ns after the first had one), all of them start on one instant
    /// start_lead_ns ahead; a session ready later starts on the next instant of that frame
    /// grid, so a latecomer or a restarted node captures in phase with the others.
    void try_start(std::int64_t now) {
        if (common_start_ns_ == 0) {
            if (first_ready_ns_ == 0) return;
            std::size_t ready = 0;
            for (const auto& [sensor, session] : latest_) {
                const Session& s = sessions_.at(session);
                ready += s.ready && !s.bye;
            }
            if (ready == 0) return;
            if (ready < rig_.sensors.size() && now - first_ready_ns_ < options_.start_wait_ns)
                return;
            common_start_ns_ = now + options_.start_lead_ns;
            for (auto& [id, s] : sessions_)
                if (s.ready && !s.started && !s.bye) {
                    s.started = true;
                    s.start_hub_ns = common_start_ns_;
                    send_start(s);
                }
            return;
        }
        for (auto& [id, s] : sessions_) {
            if (!s.ready || s.started || s.bye) continue;
            const std::int64_t period = period_ns(s);
            const std::int64_t ahead = now + options_.start_lead_ns - common_start_ns_;
            s.started = true;
            s.start_hub_ns = common_start_ns_ + (ahead + period - 1) / period * period;
            send_start(s);
        }
    }

    void schedule(std::int64_t now) {
        std::lock_guard<std::mutex> lock(mutex_);
        for (auto& [id, s] : sessions_) {
            if (s.bye) continue;
            if (s.awaiting && now - s.sent_at > options_.probe_timeout_ns) {
                s.awaiting = false;
                ++s.timeouts;
                finish_probe(s, now);
                if (s.timeouts > 3) s.next_at = now + options_.probe_interval_ns;
            }
            if (!s.awaiting && now >= s.next_at) {
                net::ControlMessage probe;
                probe.type = net::ControlType::kProbe;
                probe.seq = ++s.seq;
                s.awaiting = true;
                s.sent_at = probe.t0 = monotonic_ns();
                send(s.routing_id, probe);
            }
        }
        try_start(now);
    }

    void run() {
        zmq::message_t id, payload;
        while (!stop_) {
            zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
            try {
                zmq::poll(&item, 1, std::chrono::milliseconds(1));
                while (socket_.recv(id, zmq::recv_flags::dontwait)) {
                    if (!id.more()) {
                        ++malformed_;
                        continue;
                    }
                    if (!socket_.recv(payload, zmq::recv_flags::none)) break;
                    const std::int64_t t3 = monotonic_ns();
                    bool extra = payload.more();
                    while (payload.more() && socket_.recv(payload, zmq::recv_flags::none)) {
                    }
                    if (extra) {
                        ++malformed_;
                        continue;
                    }
                    on_message(id.to_string(), static_cast<const std::uint8_t*>(payload.data()),
                               payload.size(), t3);
                }
                schedule(monotonic_ns());
            } catch (const zmq::error_t& e) {
                if (stop_) break;
            }
        }
    }

    zmq::socket_t socket_;
    const io::Rig& rig_;
    HubOptions options_;
    cli::Context& ctx_;
    std::mutex mutex_;
    std::map<std::uint64_t, Session> sessions_;
    std::map<std::size_t, std::uint64_t> latest_;  ///< sensor -> its latest session
    std::int64_t first_ready_ns_ = 0;              ///< when the first clock was known
    std::int64_t common_start_ns_ = 0;             ///< the rig's start instant (0: not yet)
    std::atomic<std::int64_t> malformed_{0}, refused_{0};
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

}  // namespace rgbd::cli::hub
