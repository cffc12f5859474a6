#include "cli/hub_health.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

namespace rgbd::cli {

namespace {

constexpr const char* kCauseNames[] = {"nodes_behind", "hub_behind", "fusion_slow"};

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

std::string whole(double x) { return std::to_string(std::llround(x)); }
std::string percent(double share) { return whole(100.0 * share) + "%"; }
std::string one_decimal(double x) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.1f", x);
    return buffer;
}

}  // namespace

SystemSample sample_system() {
    SystemSample s;
    rusage usage{};
    if (::getrusage(RUSAGE_SELF, &usage) == 0)
        s.process_cpu_s =
            static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
            1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    std::ifstream loadavg("/proc/loadavg");
    double load = -1;
    if (loadavg >> load) s.load_1min = load;
    s.cores = std::max(1L, ::sysconf(_SC_NPROCESSORS_ONLN));
    return s;
}

HubHealth::HubHealth(HealthOptions options) : options_(std::move(options)) { reset_window(); }

void HubHealth::reset_window() {
    w_ = Window{};
    w_.late_by_sensor.assign(options_.sensor_ids.size(), 0);
}

void HubHealth::frame(std::size_t sensor, std::int64_t capture_ns, std::int64_t sent_ns,
                      std::int64_t received_ns, bool late) {
    ++w_.views;
    ++views_total_;
    if (!late) return;
    ++w_.late;
    ++late_total_;
    if (sensor < w_.late_by_sensor.size()) ++w_.late_by_sensor[sensor];
    // A late view is the node's doing when it left the node later than it waited in the hub.
    double node_ms = 1e-6 * static_cast<double>(received_ns - capture_ns), hub_ms = 0;
    if (sent_ns != kUnknown) {
        node_ms = 1e-6 * static_cast<double>(sent_ns - capture_ns);
        hub_ms = 1e-6 * static_cast<double>(received_ns - sent_ns);
    } else {
        ++w_.late_without_send_time;
    }
    w_.node_delay_ms.push_back(node_ms);
    w_.hub_delay_ms.push_back(hub_ms);
    ++causes_[node_ms >= hub_ms ? kNodesBehind : kHubBehind].count;
}

void HubHealth::fusion_totals(std::int64_t offered, std::int64_t fused, std::int64_t skipped,
                              double wall_ms, double cpu_ms) {
    causes_[kFusionSlow].count += std::max<std::int64_t>(0, skipped - skipped_);
    offered_ = offered;
    fused_ = fused;
    skipped_ = skipped;
    wall_ms_ = wall_ms;
    cpu_ms_ = cpu_ms;
}

std::vector<std::string> HubHealth::tick(std::int64_t now_ns, const SystemSample& system) {
    std::vector<std::string> lines;
    if (window_start_ns_ == kUnknown) {
        window_start_ns_ = now_ns;
        cpu_start_s_ = system.process_cpu_s;
        offered0_ = offered_, fused0_ = fused_, skipped0_ = skipped_, wall0_ms_ = wall_ms_;
        cpu0_ms_ = cpu_ms_;
        return lines;
    }
    const double window_s = 1e-9 * static_cast<double>(now_ns - window_start_ns_);
    if (window_s < options_.window_s) return lines;

    // The window's figures.
    std::int64_t late_node = 0, late_hub = 0;
    for (std::size_t i = 0; i < w_.node_delay_ms.size(); ++i)
        ++(w_.node_delay_ms[i] >= w_.hub_delay_ms[i] ? late_node : late_hub);
    const double views = static_cast<double>(std::max<std::int64_t>(1, w_.views));
    late_share_ = static_cast<double>(w_.late) / views;
    node_delay_ms_ = median(w_.node_delay_ms);
    hub_delay_ms_ = median(w_.hub_delay_ms);
    last_late_by_sensor_ = w_.late_by_sensor;
    cpu_share_ = (system.process_cpu_s - cpu_start_s_) / window_s / std::max(1, system.cores);
    const std::int64_t d_offered = offered_ - offered0_, d_skipped = skipped_ - skipped0_,
                       d_fused = fused_ - fused0_;
    skip_share_ = d_offered > 0 ? static_cast<double>(d_skipped) / d_offered : 0.0;
    fusion_ms_ = d_fused > 0 ? (wall_ms_ - wall0_ms_) / static_cast<double>(d_fused)
                             : 1e3 * window_s;  // not one set fused in the window
    fusion_cpu_ms_ = d_fused > 0 ? (cpu_ms_ - cpu0_ms_) / static_cast<double>(d_fused) : fusion_ms_;

    const bool active[kCauses] = {static_cast<double>(late_node) / views > options_.share,
                                  static_cast<double>(late_hub) / views > options_.share,
                                  options_.video && skip_share_ > options_.share};
    for (int c = 0; c < kCauses; ++c) {
        CauseState& state = causes_[c];
        if (!active[c]) {
            state.since_ns = -1;
            continue;
        }
        if (state.since_ns < 0) state.since_ns = window_start_ns_;
        state.held_s += window_s;
        const auto sustain_ns = static_cast<std::int64_t>(options_.sustain_s * 1e9);
        const auto repeat_ns = static_cast<std::int64_t>(options_.repeat_s * 1e9);
        if (now_ns - state.since_ns < sustain_ns) continue;
        if (state.warned_ns != std::numeric_limits<std::int64_t>::min() &&
            now_ns - state.warned_ns < repeat_ns)
            continue;
        state.warned_ns = now_ns;
        ++state.warnings;
        lines.push_back(message(static_cast<Cause>(c), system));
        if (printed_.size() < 20) printed_.push_back(lines.back());
    }

    // Next window.
    window_start_ns_ = now_ns;
    cpu_start_s_ = system.process_cpu_s;
    offered0_ = offered_, fused0_ = fused_, skipped0_ = skipped_, wall0_ms_ = wall_ms_;
    cpu0_ms_ = cpu_ms_;
    late_views_window_ = w_.late;
    views_window_ = w_.views;
    window_len_s_ = window_s;
    late_unknown_window_ = w_.late_without_send_time;
    d_offered_ = d_offered;
    d_skipped_ = d_skipped;
    reset_window();
    return lines;
}

std::string HubHealth::worst_sensors() const {
    std::vector<std::pair<std::int64_t, std::size_t>> late;
    for (std::size_t s = 0; s < last_late_by_sensor_.size(); ++s)
        if (last_late_by_sensor_[s] > 0) late.emplace_back(last_late_by_sensor_[s], s);
    std::sort(late.begin(), late.end(), [](const auto& a, const auto& b) {
        return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    std::string out;
    for (std::size_t k = 0; k < late.size() && k < 3; ++k)
        out += (k ? ", " : "") + options_.sensor_ids[late[k].second] + " " +
               std::to_string(late[k].first);
    if (late.size() > 3) out += ", ...";
    return out;
}

std::string HubHealth::message(Cause cause, const SystemSample& system) const {
    const std::string machine =
        "hub CPU " + percent(cpu_share_) + " of " + std::to_string(system.cores) + " cores" +
        (system.load_1min >= 0 ? ", load average " + one_decimal(system.load_1min) : std::string());
    const std::string period = whole(options_.frame_period_ms) + " ms";
    const std::string deadline =
        "the deadline is " + whole(options_.deadline_ms) + " ms (--latency-ms)";
    const std::string late =
        percent(late_share_) + " of views arrive too late (" + std::to_string(late_views_window_) +
        " of " + std::to_string(views_window_) + " in the last " + one_decimal(window_len_s_) +
        " s; late per node: " + worst_sensors() + ")";
    switch (cause) {
        case kNodesBehind:
            return late + ": " +
                   (late_unknown_window_ > 0 ? "they reach the hub " : "they leave their nodes ") +
                   whole(node_delay_ms_) + " ms after capture, " + deadline +
                   ", the frame period " + period +
                   ": the nodes' per-frame work does not keep up with their sensors (" + machine +
                   "); run fewer nodes per machine" +
                   (options_.fuse_on_nodes
                        ? std::string(", or with nodes and hub on one PC use --fuse-on hub and "
                                      "nodes without --views (the hub then fuses the newest frame "
                                      "set and skips the others; docs/method.md, \"One PC\")")
                        : std::string(" (their encoding competes with the hub for the cores)"));
        case kHubBehind:
            return late + ": they wait " + whole(hub_delay_ms_) +
                   " ms in the hub's queue before it reads them, " + deadline + " (" + machine +
                   "); give the hub a core of its own (fewer nodes on its machine) or raise "
                   "--latency-ms";
        case kFusionSlow:
        default:
            return percent(skip_share_) + " of frame sets are skipped for newer ones (" +
                   std::to_string(d_skipped_) + " of " + std::to_string(d_offered_) +
                   " in the last " + one_decimal(window_len_s_) +
                   " s): fusing one frame set takes " + whole(fusion_ms_) + " ms" +
                   (fusion_cpu_ms_ > 0 && fusion_cpu_ms_ < 0.5 * fusion_ms_
                        ? " (" + whole(fusion_cpu_ms_) +
                              " ms of CPU: it waits for a core, other processes take the machine)"
                        : std::string()) +
                   ", the frame period is " + period + " (" + machine + "); " +
                   (options_.fuse_on_nodes
                        ? std::string("give the hub a core of its own (fewer nodes on its "
                                      "machine), or a coarser --voxel-mm")
                        : std::string("move the per-view work to the nodes (--fuse-on nodes) "
                                      "when they have machines of their own, or skip the clean "
                                      "(--no-clean)"));
    }
}

Report HubHealth::report() const {
    Report causes = Report::object();
    for (int c = 0; c < kCauses; ++c)
        causes[kCauseNames[c]] = {
            {"held_s", causes_[c].held_s},
            {"warnings", causes_[c].warnings},
            {c == kFusionSlow ? "sets_skipped" : "views_late", causes_[c].count}};
    return Report{{"views", views_total_},
                  {"views_late", late_total_},
                  {"causes", causes},
                  {"warnings", printed_}};
}

}  // namespace rgbd::cli
