// The common start instant (issue 20 item 2, docs/algorithms.md §1): the hub starts every
// node of the rig on one future instant once all have joined, so the first frame set is
// complete even when the nodes' clocks are +-500 ms off; a node that joins late starts on the
// same frame grid. Checked against the nodes' true capture instants (--truth), not wall time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "io/capture_folder.hpp"
#include "tests/cli/hub_session.hpp"
#include "tests/support/capture_harness.hpp"

namespace {

using namespace rgbd::test::capture;
namespace fs = std::filesystem;
using rgbd::test::slurp;

TEST_F(RgbdCapture, EightNodesWithClocksOffStartOnOneInstant) {
    const HubSession session("start");
    const fs::path dir = temp_root();
    session.record("synth/rig.json", "rec_start",
                   "--exit-after-bye --latency-ms 2000 --metrics hub_start.json");
    const double offsets_ms[8] = {500, -500, 310, -220, 90, -430, 470, -15};
    for (int s = 0; s < 8; ++s)
        session.start_node(s, "--frames 30 --clock-offset-ms " + std::to_string(offsets_ms[s]) +
                                  " --truth truth_start_" + std::to_string(s) +
                                  ".csv --metrics node_start_" + std::to_string(s) + ".json");
    ASSERT_TRUE(session.nodes_succeed(8, 90));
    ASSERT_TRUE(session.hub_exits(0, 30));

    // Every node honoured the start; their first true capture instants coincide.
    std::int64_t first_lo = INT64_MAX, first_hi = INT64_MIN;
    std::vector<std::vector<Truth>> truths;
    for (int s = 0; s < 8; ++s) {
        const json node = read_json(dir / ("node_start_" + std::to_string(s) + ".json"));
        EXPECT_TRUE(node["start_honoured"].get<bool>()) << id(s);
        truths.push_back(read_truth(dir / ("truth_start_" + std::to_string(s) + ".csv")));
        ASSERT_EQ(truths.back().size(), 30u);
        first_lo = std::min(first_lo, truths.back().front().true_ns);
        first_hi = std::max(first_hi, truths.back().front().true_ns);
    }
    EXPECT_LT(first_hi - first_lo, 1'000'000) << "first frames not on one instant";

    // Every frame set, the first one included, holds all eight sensors, and its true spread
    // is within the tolerance.
    const json hub = read_json(dir / "hub_start.json");
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec_start");
    ASSERT_EQ(cap.framesets.size(), 30u) << hub.dump(1);
    const double tolerance_ns = hub["tolerance_ns"].get<double>();
    for (const auto& set : cap.framesets) {
        std::int64_t lo = INT64_MAX, hi = INT64_MIN;
        for (int s = 0; s < 8; ++s) {
            ASSERT_GE(set.frames[s], 0) << "set " << set.set << " misses " << id(s);
            const std::int64_t t = truths[s][static_cast<std::size_t>(set.frames[s])].true_ns;
            lo = std::min(lo, t);
            hi = std::max(hi, t);
        }
        EXPECT_LE(static_cast<double>(hi - lo), tolerance_ns) << "set " << set.set;
    }
    EXPECT_EQ(hub["framesets_complete"], 30);
}

TEST_F(RgbdCapture, ALatecomerStartsOnTheFrameGrid) {
    const HubSession session("late");
    const fs::path dir = temp_root();
    // The hub waits 1 s for the rig's second node, then starts the first alone.
    session.record(rig_of(2), "rec_late",
                   "--exit-after-bye --start-wait-s 1 --metrics hub_late.json");
    session.start_node(
        0,
        "--frames 300 --clock-offset-ms 200 --truth truth_late_0.csv --metrics node_late_0.json");
    // The second node appears once the first one streams (its truth file fills up).
    std::error_code ec;
    for (int i = 0; i < 600; ++i) {
        const auto size = fs::file_size(dir / "truth_late_0.csv", ec);
        if (!ec && size > 200) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    session.start_node(
        1,
        "--frames 30 --clock-offset-ms -300 --truth truth_late_1.csv --metrics node_late_1.json");
    ASSERT_TRUE(session.nodes_succeed(2, 90));
    ASSERT_TRUE(session.hub_exits(0, 30));
    const auto t0 = read_truth(dir / "truth_late_0.csv");
    const auto t1 = read_truth(dir / "truth_late_1.csv");
    ASSERT_EQ(t1.size(), 30u);
    ASSERT_GT(t1.front().true_ns, t0.front().true_ns) << "the second node was not late";
    // The latecomer's first instant lies on the first node's grid (whole frame periods later).
    const double period = 1e9 / 30.0;
    const double steps = static_cast<double>(t1.front().true_ns - t0.front().true_ns) / period;
    EXPECT_LT(std::abs(steps - std::round(steps)) * period, 1e6) << steps << " periods";
    // The sets holding both sensors are complete pairs with a true spread below 1 ms.
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec_late");
    int pairs = 0;
    for (const auto& set : cap.framesets) {
        if (set.frames[0] < 0 || set.frames[1] < 0) continue;
        ++pairs;
        const auto a = t0[static_cast<std::size_t>(set.frames[0])].true_ns;
        const auto b = t1[static_cast<std::size_t>(set.frames[1])].true_ns;
        EXPECT_LT(std::abs(a - b), 1'000'000) << "set " << set.set;
    }
    EXPECT_EQ(pairs, 30);
}

}  // namespace
