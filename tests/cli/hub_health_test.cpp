// rgbd-capture's health check (cli/hub_health.hpp, issue 38) fed with known timings, no clock:
// 8 sensors at 30 fps for a number of seconds, with a chosen share of late views, where they
// lost their time (on the node or in the hub's queue), and a fusion that keeps up or not. Each
// cause is named with its figures once it held for 3 s, then at most every 10 s; a healthy run
// and a short hiccup say nothing.
#include "cli/hub_health.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace {

using rgbd::cli::HealthOptions;
using rgbd::cli::HubHealth;
using rgbd::cli::SystemSample;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kPeriod = 33'333'334;  // 30 frames: just over 1 s

HealthOptions options(bool fuse_on_nodes = true) {
    HealthOptions o;
    o.deadline_ms = 200;
    o.video = true;
    o.fuse_on_nodes = fuse_on_nodes;
    for (int s = 0; s < 8; ++s) o.sensor_ids.push_back("k2-" + std::to_string(s));
    return o;
}

/// What the simulated second `second` looks like.
struct Second {
    std::vector<int> late_sensors;         ///< their views all miss their sets
    std::int64_t node_delay_ns = 5 * kMs;  ///< capture -> sent, of the late views
    std::int64_t hub_delay_ns = 1 * kMs;   ///< sent -> read by the hub, of the late views
    bool send_time = true;                 ///< the nodes give their send time
    int fused = 30, skipped = 0;           ///< fusion: sets fused / skipped of 30 offered
    double fusion_ms = 20;                 ///< wall time per fused set
    double fusion_cpu_ms = -1;             ///< its CPU time (-1: = the wall time)
};

struct Outcome {
    std::vector<std::string> lines;
    rgbd::Report report;
};

/// Feeds `seconds` seconds (each described by `at(second)`), ticking every 200 ms, with the
/// process using `cpu_per_s` s of CPU per second on 2 cores at load average 3.5.
template <typename At>
Outcome simulate(HubHealth& health, int seconds, At at, double cpu_per_s = 0.5) {
    Outcome run;
    std::int64_t offered = 0, fused = 0, skipped = 0;
    double wall = 0, cpu = 0;
    health.tick(0, SystemSample{0.0, 3.5, 2});
    for (int k = 0; k < seconds * 30; ++k) {
        const std::int64_t capture = k * kPeriod;
        const Second s = at(k / 30);
        for (int sensor = 0; sensor < 8; ++sensor) {
            const bool late = std::find(s.late_sensors.begin(), s.late_sensors.end(), sensor) !=
                              s.late_sensors.end();
            const std::int64_t sent = capture + (late ? s.node_delay_ns : 2 * kMs);
            const std::int64_t read = sent + (late ? s.hub_delay_ns : 1 * kMs);
            health.frame(sensor, capture, s.send_time ? sent : HubHealth::kUnknown, read, late);
        }
        ++offered;
        if (k % 30 < s.skipped) {
            ++skipped;
        } else if (k % 30 < s.skipped + s.fused) {
            ++fused;
            wall += s.fusion_ms;
            cpu += s.fusion_cpu_ms < 0 ? s.fusion_ms : s.fusion_cpu_ms;
        }
        health.fusion_totals(offered, fused, skipped, wall, cpu);
        if (k % 6 == 5) {  // every 200 ms
            const std::int64_t now = capture + kPeriod;
            SystemSample system{cpu_per_s * 1e-9 * static_cast<double>(now), 3.5, 2};
            for (std::string& line : health.tick(now, system)) run.lines.push_back(line);
        }
    }
    run.report = health.report();
    return run;
}

int count(const std::vector<std::string>& lines, const std::string& what) {
    int n = 0;
    for (const std::string& line : lines) n += line.find(what) != std::string::npos;
    return n;
}

TEST(HubHealth, AHealthyRunSaysNothing) {
    HubHealth health(options());
    const Outcome run = simulate(health, 30, [](int) { return Second{}; });
    EXPECT_TRUE(run.lines.empty()) << run.lines.front();
    EXPECT_EQ(run.report["views"], 8 * 30 * 30);
    EXPECT_EQ(run.report["views_late"], 0);
    for (const char* cause : {"nodes_behind", "hub_behind", "fusion_slow"}) {
        EXPECT_EQ(run.report["causes"][cause]["warnings"], 0) << cause;
        EXPECT_EQ(run.report["causes"][cause]["held_s"], 0.0) << cause;
    }
}

TEST(HubHealth, AHiccupShorterThanThreeSecondsSaysNothing) {
    HubHealth health(options());
    const Outcome run = simulate(health, 30, [](int second) {
        Second s;
        if (second >= 10 && second < 12) {  // two bad seconds: 3 nodes behind, fusion slow
            s.late_sensors = {1, 2, 3};
            s.node_delay_ns = 900 * kMs;
            s.fused = 5;
            s.skipped = 25;
        }
        return s;
    });
    EXPECT_TRUE(run.lines.empty()) << run.lines.front();
    // ... but counted.
    EXPECT_EQ(run.report["views_late"], 3 * 2 * 30);
    EXPECT_EQ(run.report["causes"]["nodes_behind"]["views_late"], 3 * 2 * 30);
    EXPECT_EQ(run.report["causes"]["fusion_slow"]["sets_skipped"], 2 * 25);
}

TEST(HubHealth, NodesBehindAreNamedWithTheirDelayOnceEveryTenSeconds) {
    HubHealth health(options());
    // Nodes k2-5 and k2-2 send their views 1.2 s after capture, from the start; k2-5 also
    // before (it is the worst).
    const Outcome run = simulate(health, 25, [](int) {
        Second s;
        s.late_sensors = {2, 5};
        s.node_delay_ns = 1200 * kMs;
        s.hub_delay_ns = 2 * kMs;
        return s;
    });
    // Held from 0 s: said at 3 s, 13 s, 23 s; nothing else.
    ASSERT_EQ(run.lines.size(), 3u) << run.lines.front();
    for (const std::string& line : run.lines) {
        EXPECT_NE(line.find("25% of views arrive too late"), std::string::npos) << line;
        EXPECT_NE(line.find("leave their nodes 1200 ms after capture"), std::string::npos) << line;
        EXPECT_NE(line.find("k2-2 30, k2-5 30"), std::string::npos) << line;
        EXPECT_NE(line.find("--latency-ms"), std::string::npos) << line;
        EXPECT_NE(line.find("fewer nodes per machine"), std::string::npos) << line;
        EXPECT_NE(line.find("--fuse-on hub"), std::string::npos) << line;
        EXPECT_NE(line.find("load average 3.5"), std::string::npos) << line;
        EXPECT_NE(line.find("hub CPU 25% of 2 cores"), std::string::npos) << line;
    }
    const auto& causes = run.report["causes"];
    EXPECT_EQ(causes["nodes_behind"]["warnings"], 3);
    EXPECT_EQ(causes["nodes_behind"]["views_late"], 2 * 25 * 30);
    EXPECT_NEAR(causes["nodes_behind"]["held_s"].get<double>(), 25.0, 1.0);
    EXPECT_EQ(causes["hub_behind"]["warnings"], 0);
    EXPECT_EQ(causes["hub_behind"]["views_late"], 0);
    EXPECT_EQ(causes["fusion_slow"]["warnings"], 0);
    EXPECT_EQ(run.report["warnings"].size(), 3u);
}

TEST(HubHealth, ViewsWaitingInTheHubsQueueBlameTheHub) {
    HubHealth health(options());
    const Outcome run = simulate(
        health, 8,
        [](int) {
            Second s;
            s.late_sensors = {0, 1, 2, 3, 4, 5, 6, 7};
            s.node_delay_ns = 10 * kMs;
            s.hub_delay_ns = 1500 * kMs;
            return s;
        },
        /*cpu_per_s=*/1.9);
    ASSERT_EQ(run.lines.size(), 1u);
    EXPECT_EQ(count(run.lines, "100% of views arrive too late"), 1) << run.lines[0];
    EXPECT_EQ(count(run.lines, "wait 1500 ms in the hub's queue"), 1) << run.lines[0];
    EXPECT_EQ(count(run.lines, "hub CPU 95% of 2 cores"), 1) << run.lines[0];
    EXPECT_EQ(run.report["causes"]["hub_behind"]["views_late"], 8 * 8 * 30);
    EXPECT_EQ(run.report["causes"]["nodes_behind"]["views_late"], 0);
}

TEST(HubHealth, NodesWithoutASendTimeAreJudgedByArrival) {
    HubHealth health(options());
    const Outcome run = simulate(health, 5, [](int) {
        Second s;
        s.late_sensors = {7};
        s.node_delay_ns = 600 * kMs;
        s.hub_delay_ns = 100 * kMs;
        s.send_time = false;
        return s;
    });
    ASSERT_EQ(run.lines.size(), 1u);
    EXPECT_EQ(count(run.lines, "they reach the hub 700 ms after capture"), 1) << run.lines[0];
    EXPECT_EQ(count(run.lines, "k2-7 30)"), 1) << run.lines[0];
}

TEST(HubHealth, SlowFusionNamesItsTimeAgainstTheFramePeriod) {
    for (const bool on_nodes : {true, false}) {
        HubHealth health(options(on_nodes));
        const Outcome run = simulate(health, 6, [](int) {
            Second s;
            s.fused = 5;
            s.skipped = 25;
            s.fusion_ms = 180;
            return s;
        });
        ASSERT_EQ(run.lines.size(), 1u);
        const std::string& line = run.lines[0];
        EXPECT_NE(line.find("83% of frame sets are skipped"), std::string::npos) << line;
        EXPECT_NE(line.find("fusing one frame set takes 180 ms, the frame period is 33 ms"),
                  std::string::npos)
            << line;
        EXPECT_EQ(line.find("--voxel-mm") != std::string::npos, on_nodes) << line;
        EXPECT_EQ(line.find("--no-clean") != std::string::npos, !on_nodes) << line;
        EXPECT_EQ(line.find("--fuse-on nodes") != std::string::npos, !on_nodes) << line;
        EXPECT_EQ(run.report["causes"]["fusion_slow"]["sets_skipped"], 6 * 25);
        EXPECT_EQ(run.report["causes"]["fusion_slow"]["warnings"], 1);
        EXPECT_EQ(run.report["views_late"], 0);
        EXPECT_EQ(line.find("waits for a core"), std::string::npos) << line;
    }
}

TEST(HubHealth, AFusionStarvedOfCpuSaysSo) {
    HubHealth health(options());
    const Outcome run = simulate(health, 4, [](int) {
        Second s;
        s.fused = 8;
        s.skipped = 22;
        s.fusion_ms = 117;
        s.fusion_cpu_ms = 5;
        return s;
    });
    ASSERT_EQ(run.lines.size(), 1u);
    EXPECT_NE(run.lines[0].find("takes 117 ms (5 ms of CPU: it waits for a core"),
              std::string::npos)
        << run.lines[0];
}

TEST(HubHealth, WithoutVideoFusionIsNotWatched) {
    HealthOptions o = options();
    o.video = false;
    HubHealth health(o);
    const Outcome run = simulate(health, 6, [](int) {
        Second s;
        s.fused = 0;
        s.skipped = 0;
        return s;
    });
    EXPECT_TRUE(run.lines.empty());
}

TEST(HubHealth, SampleSystemReadsThisMachine) {
    const SystemSample s = rgbd::cli::sample_system();
    EXPECT_GE(s.cores, 1);
    EXPECT_GE(s.process_cpu_s, 0.0);
    EXPECT_GE(s.load_1min, 0.0);  // Linux: /proc/loadavg
}

}  // namespace
