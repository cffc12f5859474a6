// Why the hub falls behind (issue 38): rgbd-capture watches, for every node and for itself, the
// causes of views that arrive too late or frame sets that are skipped, and says which one holds
// and what to change, once per cause and at most every --health-repeat-s seconds, instead of
// only counting late frames. Causes (window by window, each window `window_s` of hub time):
//  - nodes behind: views arrive after their frame set's deadline (rgbd-capture --latency-ms)
//    and they left their node late (node send time - capture instant, both in the node's clock,
//    from the frame header): the node's per-view work or its machine is slower than the frames;
//  - hub behind: late views that left their node in time but waited in the hub's socket before
//    the hub read them (hub receive time - send time mapped to hub time): the hub's CPU;
//  - fusion slow: frame sets skipped for newer ones because fusing one set takes longer than
//    the frame period (rgbd-capture --video).
// Each warning names the figures (late share, delays, fusion time per set vs frame period, hub
// CPU as a share of the machine's cores, load average) and the options that help. Everything is
// fed with explicit times, so tests drive it without a clock; sample_system() reads the process
// CPU (getrusage) and the machine's load (/proc/loadavg, nproc).
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "toolkit/report.hpp"

namespace rgbd::cli {

/// Process CPU and machine load at one instant.
struct SystemSample {
    double process_cpu_s = 0;  ///< user + system CPU of the whole process so far (s)
    double load_1min = -1;     ///< /proc/loadavg's first figure (-1 = unknown)
    int cores = 1;             ///< online cores (nproc)
};

/// Reads getrusage(RUSAGE_SELF), /proc/loadavg and sysconf(_SC_NPROCESSORS_ONLN).
SystemSample sample_system();

struct HealthOptions {
    double frame_period_ms = 1000.0 / 30.0;  ///< the sensors' frame period
    double deadline_ms = 1000.0;             ///< rgbd-capture --latency-ms
    double window_s = 1.0;                   ///< length of one evaluation window (hub time)
    double sustain_s = 3.0;                  ///< a cause holds this long before it is reported
    double repeat_s = 10.0;                  ///< at most one warning per cause this often
    double share = 0.05;        ///< late views / skipped sets above this share name a cause
    bool fuse_on_nodes = true;  ///< --fuse-on nodes (the remedies differ)
    bool video = false;         ///< --video: fusion is watched
    std::vector<std::string> sensor_ids;  ///< rig order
};

class HubHealth {
public:
    enum Cause { kNodesBehind = 0, kHubBehind = 1, kFusionSlow = 2, kCauses = 3 };
    static constexpr std::int64_t kUnknown = std::numeric_limits<std::int64_t>::min();

    explicit HubHealth(HealthOptions options);

    /// Hub thread, per received frame or view of sensor `sensor` (rig order): its capture
    /// instant, the instant its node sent it (kUnknown for nodes without a send time), both
    /// mapped to hub time, the hub time it was read, and whether it missed its frame set.
    void frame(std::size_t sensor, std::int64_t capture_ns, std::int64_t sent_ns,
               std::int64_t received_ns, bool late);
    /// Totals of the fusion so far (VideoStream::totals): sets offered, fused, skipped, and
    /// the wall and CPU time of the fusion thread (ms; wall well above CPU: the fusion waits
    /// for a core, other processes take the machine).
    void fusion_totals(std::int64_t offered, std::int64_t fused, std::int64_t skipped,
                       double wall_ms, double cpu_ms = 0);
    /// Closes the window when `now_ns` passed its end; returns the warning lines due (without
    /// the tool's prefix), one per cause at most.
    std::vector<std::string> tick(std::int64_t now_ns, const SystemSample& system);

    /// Per cause: seconds it held, warnings printed, views late / sets skipped while it held;
    /// the whole run's late views and skipped sets; the warnings printed (the first 20).
    Report report() const;

private:
    struct Window {
        std::int64_t views = 0, late = 0;
        std::vector<std::int64_t> late_by_sensor;
        std::vector<double> node_delay_ms, hub_delay_ms;  ///< of the late views
        std::int64_t late_without_send_time = 0;
    };
    struct CauseState {
        std::int64_t since_ns = -1;  ///< start of the current run of windows it held (-1 none)
        std::int64_t warned_ns = std::numeric_limits<std::int64_t>::min();
        double held_s = 0;
        std::int64_t warnings = 0, count = 0;
    };
    std::string message(Cause cause, const SystemSample& system) const;
    std::string worst_sensors() const;
    void reset_window();

    HealthOptions options_;
    Window w_;
    std::int64_t window_start_ns_ = kUnknown;
    double cpu_start_s_ = -1;
    // fusion totals: at the window start and now
    std::int64_t offered0_ = 0, fused0_ = 0, skipped0_ = 0, offered_ = 0, fused_ = 0, skipped_ = 0;
    double wall0_ms_ = 0, wall_ms_ = 0, cpu0_ms_ = 0, cpu_ms_ = 0;
    // figures of the last closed window, for the messages
    double late_share_ = 0, node_delay_ms_ = 0, hub_delay_ms_ = 0, skip_share_ = 0, fusion_ms_ = 0,
           fusion_cpu_ms_ = 0, cpu_share_ = 0;
    std::vector<std::int64_t> last_late_by_sensor_;
    std::int64_t late_views_window_ = 0, views_window_ = 0, late_unknown_window_ = 0,
                 d_offered_ = 0, d_skipped_ = 0;
    double window_len_s_ = 0;
    CauseState causes_[kCauses];
    std::int64_t views_total_ = 0, late_total_ = 0;
    std::vector<std::string> printed_;
};

}  // namespace rgbd::cli
