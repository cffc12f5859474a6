// rgbd-capture says why views are late (issue 38, cli/hub_health.hpp) with real nodes on
// loopback: a node made slower than its sensor (rgbd-node --work-delay-ms, a test hook) falls
// further behind with every frame; once its views miss their sets for 3 s the hub names the
// node, how long after capture its views leave it, and the remedy, and counts the late views
// under "nodes behind" in --metrics. Two healthy nodes give no such warning. No wall-clock
// limits beyond generous hang guards: a loaded machine only makes the slow node slower.
#include <gtest/gtest.h>

#include "tests/cli/hub_port.hpp"
#include "tests/support/capture_harness.hpp"

namespace {

using namespace rgbd::test::capture;

/// Two nodes replaying the synthetic capture into a recording hub with --latency-ms 200;
/// node 1 spends `delay_ms` more on every frame. Returns the hub's metrics and its stderr.
std::pair<json, std::string> run_two(const std::string& name, const std::string& rig,
                                     double delay_ms, int frames1) {
    const fs::path dir = temp_root();
    fs::remove_all(dir / name);
    const HubPort port;
    start(dir, "hub_" + name,
          "$BIN/rgbd-capture --rig " + rig + " -o " + name + " --exit-after-bye --latency-ms 200" +
              port.listen() + " --metrics hub_" + name + ".json");
    start(dir, name + "_node0",
          "$BIN/rgbd-node --sensor playback:synth#k2-0 --loop --frames 240" + port.hub());
    start(dir, name + "_node1",
          "$BIN/rgbd-node --sensor playback:synth#k2-1 --loop --frames " + std::to_string(frames1) +
              " --work-delay-ms " + std::to_string(delay_ms) + port.hub());
    for (int s = 0; s < 2; ++s)
        EXPECT_EQ(wait_for(dir, name + "_node" + std::to_string(s), 300), 0)
            << slurp(dir / (name + "_node" + std::to_string(s) + ".err"));
    EXPECT_EQ(wait_for(dir, "hub_" + name, 120), 0) << slurp(dir / ("hub_" + name + ".err"));
    return {read_json(dir / ("hub_" + name + ".json")), slurp(dir / ("hub_" + name + ".err"))};
}

TEST_F(RgbdCapture, ASlowNodeIsNamedAsTheReasonViewsAreLate) {
    // 80 ms per frame against a 33 ms period: 47 ms further behind with every frame, past the
    // 200 ms deadline after 5 frames, then every view late for the rest of its 90 frames (7 s).
    const auto [hub, err] = run_two("slow", rig_of(2), 80, 90);
    const json& h = hub["health"];
    EXPECT_GT(hub["late_frames"].get<int>(), 30) << hub.dump(1);
    EXPECT_EQ(h["views_late"], hub["late_frames"]);
    EXPECT_EQ(h["causes"]["nodes_behind"]["views_late"], h["views_late"]) << h.dump(1);
    EXPECT_GE(h["causes"]["nodes_behind"]["warnings"].get<int>(), 1) << h.dump(1) << err;
    EXPECT_EQ(h["causes"]["hub_behind"]["warnings"], 0) << err;
    // One line naming the cause, the node and the remedy.
    const std::string prefix = "rgbd-capture: warning: ";
    const auto at = err.find(prefix);
    ASSERT_NE(at, std::string::npos) << err;
    const std::string line = err.substr(at, err.find('\n', at) - at);
    EXPECT_NE(line.find("of views arrive too late"), std::string::npos) << line;
    EXPECT_NE(line.find("late per node: k2-1 "), std::string::npos) << line;
    EXPECT_EQ(line.find("k2-0"), std::string::npos) << line;
    EXPECT_NE(line.find("leave their nodes"), std::string::npos) << line;
    EXPECT_NE(line.find("fewer nodes per machine"), std::string::npos) << line;
    EXPECT_NE(line.find("cores"), std::string::npos) << line;
    // The node's delay when the warning came (>= 3 s of falling behind) is past the deadline.
    const auto ms = line.find(" ms after capture");
    ASSERT_NE(ms, std::string::npos) << line;
    const auto digits = line.rfind(' ', ms - 1);
    EXPECT_GT(std::stod(line.substr(digits + 1, ms - digits - 1)), 200.0) << line;
    EXPECT_NE(err.find("late: "), std::string::npos) << err;  // the summary line
}

TEST_F(RgbdCapture, HealthyNodesGiveNoWarning) {
    const auto [hub, err] = run_two("healthy", rig_of(2), 0, 240);
    EXPECT_EQ(err.find("warning"), std::string::npos) << err;
    const json& h = hub["health"];
    EXPECT_EQ(h["views"], hub["frames_received"]);
    for (const char* cause : {"nodes_behind", "hub_behind", "fusion_slow"})
        EXPECT_EQ(h["causes"][cause]["warnings"], 0) << cause << h.dump(1);
    EXPECT_EQ(h["warnings"].size(), 0u);
}

}  // namespace
