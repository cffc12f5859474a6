// Contract and system tests of the capture network: rgbd-capture (hub) and rgbd-node run as
// separate processes on loopback, replaying an 8-Kinect rgbd-synth capture at 30 fps with
// injected clock offsets (up to +-500 ms) and drifts (up to +-50 ppm). Checks: zero lost
// frames, every recorded time within 1 ms of the true capture instant (so the offset
// estimates are within 1 ms), or, on a machine too loaded for that, within what the hub's
// measured probe round trips guarantee (clock_error_bound_ns, capped at 30.1 ms: under a
// frame period, so every recorded time names its frame whatever round trips the hub reports;
// the drift within at most 40 ppm, so a drift ignored or of the wrong sign fails), every frame
// set's true spread within the tolerance plus twice that error, recorded depth identical to the
// source; a node killed and restarted; garbage and truncated messages; CURVE keys; a full disk
// (root only). The loopback run lasts RGBD_CAPTURE_SECONDS (default 10;
// validation/robustness/capture_60s.sh runs 60).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <zmq.hpp>

#include "io/capture_folder.hpp"
#include "io/ply_stream.hpp"
#include "io/rvl.hpp"
#include "sensors/network/protocol.hpp"
#include "tests/cli/hub_session.hpp"
#include "tests/cli/usage_error.hpp"
#include "tests/support/capture_harness.hpp"
#include "tests/support/ellipsoid_off.hpp"
#include "tests/support/tool_runner.hpp"

namespace {

// The harness's namespace also brings fs, json, Outcome and slurp.
using namespace rgbd::test::capture;
using rgbd::test::is_usage_error;

TEST_F(RgbdCapture, HelpAndUsageErrors) {
    for (const char* tool : {"rgbd-capture", "rgbd-node"}) {
        Outcome r = run(std::string("$BIN/") + tool + " --help");
        EXPECT_EQ(r.code, 0);
        EXPECT_NE(r.out.find("Usage: "), std::string::npos);
        EXPECT_NE(r.out.find("Example:"), std::string::npos);
    }
    EXPECT_TRUE(is_usage_error(run("$BIN/rgbd-capture -o x"), "rgbd-capture: error: --rig"));
    EXPECT_TRUE(
        is_usage_error(run("$BIN/rgbd-node --hub tcp://127.0.0.1:9"), "--sensor is required"));
    EXPECT_TRUE(is_usage_error(run("$BIN/rgbd-node --sensor synthetic: --clock-drift-ppm 1e9")));
    EXPECT_TRUE(
        is_usage_error(run("$BIN/rgbd-capture --rig synth/rig.json -o x --tolerance-ms -1")));
    EXPECT_FALSE(fs::exists(temp_root() / "x"));
}

TEST_F(RgbdCapture, BadInputIsOneLineNamingTheProblemWithoutOutput) {
    std::ofstream(temp_root() / "broken_rig.json") << "{\"format\": \"rgbd-capture\", ";
    Outcome r =
        run("$BIN/rgbd-capture --rig broken_rig.json -o out_broken --listen tcp://127.0.0.1:" +
            std::to_string(free_port()));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("broken_rig.json"), std::string::npos) << r.err;
    EXPECT_EQ(rgbd::test::line_count(r.err), 1) << r.err;
    EXPECT_FALSE(fs::exists(temp_root() / "out_broken"));
    // An existing, non-empty output folder is refused and left alone.
    fs::create_directories(temp_root() / "full_out");
    std::ofstream(temp_root() / "full_out" / "keep.txt") << "x";
    r = run("$BIN/rgbd-capture --rig synth/rig.json -o full_out --listen tcp://127.0.0.1:" +
            std::to_string(free_port()));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("full_out"), std::string::npos) << r.err;
    EXPECT_EQ(fs::directory_iterator(temp_root() / "full_out")->path().filename(), "keep.txt");
    // A sensor that does not exist, a key file that is not one.
    r = run("$BIN/rgbd-node --sensor playback:synth#nope");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("nope"), std::string::npos) << r.err;
    std::ofstream(temp_root() / "bad.key") << "server_public=short\n";
    r = run("$BIN/rgbd-node --sensor synthetic: --key bad.key");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("bad.key:1"), std::string::npos) << r.err;
    r = run("$BIN/rgbd-node --sensor synthetic: --hub tcp://127.0.0.1:" +
            std::to_string(free_port()) + " --start-timeout-s 0.5");
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("no answer from the hub"), std::string::npos) << r.err;
}

TEST_F(RgbdCapture, EightNodesOnLoopbackLoseNothingAndStayInSync) {
    const char* env = std::getenv("RGBD_CAPTURE_SECONDS");
    const double seconds = env ? std::atof(env) : 10.0;
    const int frames = static_cast<int>(std::lround(seconds * 30));
    const HubSession session("8");
    const fs::path dir = temp_root();
    std::mt19937 rng(8);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    session.record("synth/rig.json", "rec8",
                   "--exit-after-bye --probe-interval-ms 500 --latency-ms 2000 "
                   "--metrics hub8.json");
    std::vector<double> offsets, drifts;
    for (int s = 0; s < 8; ++s) {
        offsets.push_back(s == 0 ? 500.0 : s == 1 ? -500.0 : 500.0 * uni(rng));
        drifts.push_back(s == 0 ? 50.0 : s == 1 ? -50.0 : 50.0 * uni(rng));
        session.start_node(s, "--frames " + std::to_string(frames) + " --clock-offset-ms " +
                                  std::to_string(offsets.back()) + " --clock-drift-ppm " +
                                  std::to_string(drifts.back()) + " --truth truth8_" +
                                  std::to_string(s) + ".csv --metrics node8_" + std::to_string(s) +
                                  ".json");
    }
    ASSERT_TRUE(session.nodes_succeed(8, seconds + 60));
    ASSERT_TRUE(session.hub_exits(0, 30));

    const json hub = read_json(dir / "hub8.json");
    EXPECT_EQ(hub["dropped_messages"], 0);
    // A frame that reaches the hub after --latency-ms (2 s) is recorded but in no frame set;
    // on a quiet machine none is, under heavy load (20 processes on 2 cores) some are.
    const std::int64_t late = hub["late_frames"].get<std::int64_t>();
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec8");
    ASSERT_EQ(cap.rig.sensors.size(), 8u);
    std::map<std::string, std::vector<Truth>> truths;
    double worst_offset_ns = 0, worst_frame_ns = 0, worst_bound_ns = 0, worst_rtt_ns = 0;
    for (int s = 0; s < 8; ++s) {
        const json node = read_json(dir / ("node8_" + std::to_string(s) + ".json"));
        const auto truth = read_truth(dir / ("truth8_" + std::to_string(s) + ".csv"));
        ASSERT_EQ(node["frames_sent"], frames);
        ASSERT_EQ(truth.size(), static_cast<std::size_t>(frames));
        const auto& recorded = cap.frames.at(id(s));
        ASSERT_EQ(recorded.size(), truth.size()) << "lost frames of " << id(s);
        // Offset estimate at the end of the run against the injected clock. What this proves:
        // the estimate is within what the hub's measured round trips allow (1 ms on a quiet
        // machine), and never looser than the harness's caps however slow the hub says its
        // round trips were (tests/support/capture_harness.hpp).
        const json& clock = hub["sensors"][id(s)]["clock"];
        const double bound = clock_error_bound_ns(clock);
        worst_bound_ns = std::max(worst_bound_ns, bound);
        worst_rtt_ns = std::max(worst_rtt_ns, clock["max_round_trip_ns"].get<double>());
        const double at = clock["at_hub_ns"].get<double>();
        const double true_offset =
            offsets[s] * 1e6 + drifts[s] * 1e-6 * (at - node["clock_epoch_ns"].get<double>());
        const double err = std::abs(clock["offset_ns"].get<double>() - true_offset);
        worst_offset_ns = std::max(worst_offset_ns, err);
        EXPECT_LT(err, bound) << id(s) << ", probe round trips up to " << clock["max_round_trip_ns"]
                              << " ns";
        EXPECT_NEAR(clock["drift_ppm"].get<double>(), drifts[s],
                    drift_error_bound_ppm(clock, seconds))
            << id(s) << ", probe round trips up to " << clock["max_round_trip_ns"] << " ns";
        // Every frame: recorded hub time vs the true capture instant; depth bit for bit.
        for (std::size_t k = 0; k < recorded.size(); ++k) {
            const double e = std::abs(static_cast<double>(recorded[k].time_ns - truth[k].true_ns));
            worst_frame_ns = std::max(worst_frame_ns, e);
            ASSERT_LT(e, bound) << id(s) << " frame " << k << ", probe round trips up to "
                                << clock["max_round_trip_ns"] << " ns";
            if (k % 3 == 0 || k + 1 == recorded.size()) {
                const cv::Mat depth = cv::imread(
                    (dir / "rec8" / id(s) / recorded[k].depth).string(), cv::IMREAD_UNCHANGED);
                ASSERT_EQ(depth.type(), CV_16UC1);
                ASSERT_EQ(cv::norm(depth, source_depth(id(s), truth[k].position), cv::NORM_INF),
                          0.0)
                    << id(s) << " frame " << k;
            }
        }
        truths[id(s)] = truth;
    }
    // Frame sets: true spread within the tolerance (the hub groups recorded times, each within
    // worst_bound_ns of the truth), frames used once, and complete while all eight nodes were
    // streaming (nodes start and stop at slightly different times).
    const double tolerance_ns = hub["tolerance_ns"].get<double>();
    std::int64_t all_from = INT64_MIN, all_to = INT64_MAX;
    for (int s = 0; s < 8; ++s) {
        all_from = std::max(all_from, truths[id(s)].front().true_ns);
        all_to = std::min(all_to, truths[id(s)].back().true_ns);
    }
    ASSERT_LT(all_from, all_to) << "the nodes never streamed at the same time";
    std::size_t complete = 0, inside = 0;
    std::int64_t incomplete_inside = 0;
    std::map<std::string, std::set<std::int64_t>> used;
    for (const auto& set : cap.framesets) {
        std::int64_t lo = INT64_MAX, hi = INT64_MIN;
        int present = 0;
        for (int s = 0; s < 8; ++s) {
            const std::int64_t f = set.frames[s];
            if (f < 0) continue;
            ++present;
            ASSERT_TRUE(used[id(s)].insert(f).second) << "frame used twice";
            const std::int64_t t = truths[id(s)][static_cast<std::size_t>(f)].true_ns;
            lo = std::min(lo, t);
            hi = std::max(hi, t);
        }
        ASSERT_GT(present, 0);
        EXPECT_LE(static_cast<double>(hi - lo), tolerance_ns + 2 * worst_bound_ns)
            << "set " << set.set;
        complete += present == 8;
        if (lo >= all_from && hi <= all_to) {
            ++inside;
            incomplete_inside += present != 8;
        }
    }
    // Every frame is in one set, but for late ones (recorded, in no set).
    std::size_t in_sets = 0;
    for (int s = 0; s < 8; ++s) in_sets += used[id(s)].size();
    EXPECT_EQ(static_cast<std::int64_t>(in_sets) + late, 8 * frames);
    EXPECT_GT(inside, static_cast<std::size_t>(frames) / 2);
    // Complete while all eight streamed, but for sets a late frame left.
    EXPECT_LE(incomplete_inside, late) << late << " late frames";
    RecordProperty("worst_offset_error_us", std::to_string(worst_offset_ns / 1e3));
    RecordProperty("worst_frame_time_error_us", std::to_string(worst_frame_ns / 1e3));
    RecordProperty("worst_probe_round_trip_us", std::to_string(worst_rtt_ns / 1e3));
    std::cout << "[ capture ] " << frames << " frames x 8 nodes, 0 lost; worst offset error "
              << worst_offset_ns / 1e3 << " us; worst frame time error " << worst_frame_ns / 1e3
              << " us (bound " << worst_bound_ns / 1e3 << " us, probe round trips up to "
              << worst_rtt_ns / 1e3 << " us); " << complete << " of " << cap.framesets.size()
              << " frame sets complete; " << late << " late frames\n";
    fs::remove_all(dir / "rec8");
}

TEST_F(RgbdCapture, KilledNodeRestartsAndTheGapIsRecorded) {
    const HubSession session("kill");
    const fs::path dir = temp_root();
    session.record(rig_of(3), "rec_kill",
                   "--exit-after-bye --probe-interval-ms 500 --metrics hub_kill.json");
    for (int s = 0; s < 3; ++s)
        session.start_node(s, "--frames 150 --clock-offset-ms " + std::to_string(100 * s - 100) +
                                  " --metrics node_kill_" + std::to_string(s) + ".json");
    // Kill node 1 once the hub has recorded half a second of its frames (on a loaded machine
    // a fixed wait could end before the node streamed at all, and there would be no gap).
    const fs::path frames_csv = dir / "rec_kill" / id(1) / "frames.csv";
    for (int k = 0; k < 600 && rgbd::test::line_count(slurp(frames_csv)) < 16; ++k)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ASSERT_EQ(::kill(pid_of(dir, "node_kill_1"), SIGKILL), 0);
    EXPECT_NE(wait_for(dir, "node_kill_1", 10), 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(1000));
    start(dir, "node_kill_1b",
          "$BIN/rgbd-node --sensor playback:synth#" + id(1) + " --loop --frames 30" +
              session.port.hub() + " --clock-offset-ms 250 --metrics node_kill_1b.json");
    for (const char* n : {"node_kill_0", "node_kill_2", "node_kill_1b"})
        ASSERT_EQ(wait_for(dir, n, 60), 0) << slurp(dir / (std::string(n) + ".err"));
    ASSERT_TRUE(session.hub_exits(0, 30));

    const json hub = read_json(dir / "hub_kill.json");
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec_kill");
    for (int s : {0, 2})
        EXPECT_EQ(cap.frames.at(id(s)).size(), 150u) << "the other nodes lost nothing";
    const json& killed = hub["sensors"][id(1)];
    EXPECT_EQ(killed["clock"]["sessions"], 2);
    ASSERT_GE(killed["gaps"].size(), 1u);
    const double gap_s =
        1e-9 * (killed["gaps"][0][1].get<double>() - killed["gaps"][0][0].get<double>());
    EXPECT_GT(gap_s, 0.5);
    // The restarted node's frames are recorded after the gap, all of them.
    const json n1b = read_json(dir / "node_kill_1b.json");
    EXPECT_GE(static_cast<std::int64_t>(cap.frames.at(id(1)).size()),
              n1b["frames_sent"].get<std::int64_t>() + 1);
    // Frame sets during the gap miss sensor 1 and have the others.
    std::size_t gap_sets = 0;
    for (const auto& set : cap.framesets)
        if (set.frames[1] < 0 && set.frames[0] >= 0 && set.frames[2] >= 0) ++gap_sets;
    EXPECT_GE(gap_sets, 15u);
}

TEST_F(RgbdCapture, GarbageAndTruncatedMessagesAreDroppedAndCounted) {
    const HubSession session("junk");
    const HubPort& port = session.port;
    const fs::path dir = temp_root();
    session.record(rig_of(2), "rec_junk", "--exit-after-bye --metrics hub_junk.json");
    for (int s = 0; s < 2; ++s)
        session.start_node(s, "--frames 90 --metrics node_junk_" + std::to_string(s) + ".json");
    // A rogue sender: garbage, truncated and corrupted frames, multi-part junk, and a
    // well-formed frame from a session the hub never heard of.
    zmq::context_t context(1);
    zmq::socket_t push(context, zmq::socket_type::push);
    push.set(zmq::sockopt::linger, 2000);
    push.connect("tcp://127.0.0.1:" + std::to_string(port.number));
    zmq::socket_t dealer(context, zmq::socket_type::dealer);
    dealer.set(zmq::sockopt::linger, 2000);
    dealer.connect("tcp://127.0.0.1:" + std::to_string(port.number + 1));
    std::mt19937 rng(1);
    rgbd::sensors::net::FrameHeader h;
    h.session = 42;
    h.sensor_id = id(0);
    h.width = 512;
    h.height = 424;
    std::vector<std::uint16_t> depth(512 * 424, 1500);
    std::vector<std::uint8_t> rvl, frame;
    rgbd::io::rvl_compress(depth.data(), depth.size(), rvl);
    const std::vector<std::uint8_t> jpeg(1000, 7);
    rgbd::sensors::net::encode_frame(h, rvl.data(), rvl.size(), jpeg.data(), jpeg.size(), frame);
    int sent = 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(800));
    for (int k = 0; k < 10; ++k) {
        std::vector<std::uint8_t> junk(1 + rng() % 5000);
        for (auto& b : junk) b = static_cast<std::uint8_t>(rng());
        push.send(zmq::buffer(junk));                                           // garbage
        push.send(zmq::buffer(frame.data(), frame.size() - 1 - rng() % 2000));  // truncated
        auto flipped = frame;
        flipped[200 + rng() % (frame.size() - 200)] ^= 0x10;
        push.send(zmq::buffer(flipped));                               // corrupt payload
        push.send(zmq::buffer(frame));                                 // unknown session
        push.send(zmq::str_buffer("part"), zmq::send_flags::sndmore);  // multi-part
        push.send(zmq::buffer(junk));
        dealer.send(zmq::buffer(junk));  // control garbage
        sent += 5;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_TRUE(session.nodes_succeed(2, 60));
    ASSERT_TRUE(session.hub_exits(0, 30));
    const json hub = read_json(dir / "hub_junk.json");
    EXPECT_EQ(hub["dropped_messages"], sent) << hub.dump(2);
    EXPECT_EQ(hub["malformed_control_messages"], 10);
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec_junk");
    for (int s = 0; s < 2; ++s) EXPECT_EQ(cap.frames.at(id(s)).size(), 90u);
}

TEST_F(RgbdCapture, CurveKeyEncryptsAndRefusesNodesWithoutTheKey) {
    if (!zmq_has("curve")) GTEST_SKIP() << "this libzmq has no CURVE support";
    const HubPort port;
    const fs::path dir = temp_root();
    fs::remove_all(dir / "rec_curve");
    fs::remove(dir / "hub.key");
    fs::remove(dir / "other.key");
    Outcome r =
        run("$BIN/rgbd-capture --make-key hub.key && $BIN/rgbd-capture --make-key other.key");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(fs::status(dir / "hub.key").permissions() & fs::perms::others_read, fs::perms::none);
    r = run("$BIN/rgbd-capture --make-key hub.key");
    EXPECT_EQ(r.code, 1) << "a key file is never overwritten";
    // Right server key, wrong client key: the hub's ZAP handler refuses it.
    {
        std::string mixed;
        std::istringstream a(slurp(dir / "hub.key")), b(slurp(dir / "other.key"));
        std::string line;
        while (std::getline(a, line))
            if (line.rfind("server_", 0) == 0) mixed += line + "\n";
        while (std::getline(b, line))
            if (line.rfind("client_", 0) == 0) mixed += line + "\n";
        std::ofstream(dir / "mixed.key") << mixed;
    }
    const std::string rig = rig_of(1);
    start(dir, "hub_curve",
          "$BIN/rgbd-capture --rig " + rig + " -o rec_curve --key hub.key" + port.listen() +
              " --exit-after-bye --metrics hub_curve.json");
    start(
        dir, "node_plain",
        "$BIN/rgbd-node --sensor playback:synth#k2-0 --frames 10 --start-timeout-s 3" + port.hub());
    start(dir, "node_mixed",
          "$BIN/rgbd-node --sensor playback:synth#k2-0 --frames 10 --start-timeout-s 3 "
          "--key mixed.key" +
              port.hub());
    EXPECT_EQ(wait_for(dir, "node_plain", 20), 1);
    EXPECT_NE(slurp(dir / "node_plain.err").find("no answer from the hub"), std::string::npos);
    EXPECT_EQ(wait_for(dir, "node_mixed", 20), 1);
    start(dir, "node_curve",
          "$BIN/rgbd-node --sensor playback:synth#k2-0 --loop --frames 30 --key hub.key" +
              port.hub());
    ASSERT_EQ(wait_for(dir, "node_curve", 30), 0) << slurp(dir / "node_curve.err");
    ASSERT_EQ(wait_for(dir, "hub_curve", 30), 0) << slurp(dir / "hub_curve.err");
    const json hub = read_json(dir / "hub_curve.json");
    EXPECT_GE(hub["refused_connections"].get<int>(), 1);
    EXPECT_EQ(hub["frames_recorded"], 30);
    EXPECT_EQ(rgbd::io::open_capture(dir / "rec_curve").frames.at("k2-0").size(), 30u);
}

TEST_F(RgbdCapture, FullDiskStopsTheRecordingWithWhatWasWrittenIntact) {
    const fs::path dir = temp_root();
    const fs::path mount = dir / "small_disk";
    const SmallDisk disk(mount, "6m");
    if (!disk.mounted()) GTEST_SKIP() << disk.why();
    const HubSession session("full");
    session.record(rig_of(2), "small_disk/rec", "--exit-after-bye --metrics hub_full.json");
    session.start_nodes(2, "--frames 300 --send-timeout-s 3");
    EXPECT_TRUE(session.hub_exits(1, 60));
    const std::string err = slurp(dir / "hub_full.err");
    EXPECT_NE(err.find("recording stopped"), std::string::npos) << err;
    EXPECT_NE(err.find("disk full"), std::string::npos) << err;
    session.stop_nodes(2, 20);
    // What is on the disk is a readable capture: every listed frame exists and equals the
    // source, every frame set refers to listed frames; no temporary files are left.
    const rgbd::io::Capture cap = rgbd::io::open_capture(mount / "rec");
    std::size_t frames = 0;
    for (int s = 0; s < 2; ++s) {
        for (const auto& f : cap.frames.at(id(s))) {
            const cv::Mat d =
                cv::imread((mount / "rec" / id(s) / f.depth).string(), cv::IMREAD_UNCHANGED);
            ASSERT_EQ(d.type(), CV_16UC1) << f.depth;
            bool matches = false;
            for (int p = 0; p < 4 && !matches; ++p)
                matches = cv::norm(d, source_depth(id(s), p), cv::NORM_INF) == 0.0;
            EXPECT_TRUE(matches) << f.depth;
            ASSERT_FALSE(cv::imread((mount / "rec" / id(s) / f.color).string()).empty());
            ++frames;
        }
    }
    EXPECT_GT(frames, 2u);
    for (const auto& set : cap.framesets)
        for (int s = 0; s < 2; ++s)
            if (set.frames[s] >= 0) {
                EXPECT_TRUE(cap.find_frame(id(s), set.frames[s]).has_value());
            }
    for (const auto& e : fs::recursive_directory_iterator(mount / "rec"))
        EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
}

TEST_F(RgbdCapture, LossAndDelayBetweenNetworkNamespaces) {
    if (::geteuid() != 0) GTEST_SKIP() << "needs root to create network namespaces";
    if (std::system("command -v ip >/dev/null 2>&1") != 0) GTEST_SKIP() << "no 'ip' (iproute2)";
    const std::string tag = std::to_string(::getpid() % 100000);
    const std::string hub_ns = "rgbdh" + tag, node_ns = "rgbdn" + tag;
    const std::string setup =
        "set -e; ip netns add " + hub_ns + "; ip netns add " + node_ns + "; ip link add vh" + tag +
        " type veth peer name vhp" + tag + "; ip link add vn" + tag + " type veth peer name vnp" +
        tag + "; ip link set vhp" + tag + " netns " + hub_ns + "; ip link set vnp" + tag +
        " netns " + node_ns + "; ip addr add 10.77.1.1/24 dev vh" + tag + "; ip link set vh" + tag +
        " up; ip addr add 10.77.2.1/24 dev vn" + tag + "; ip link set vn" + tag + " up; ip -n " +
        hub_ns + " addr add 10.77.1.2/24 dev vhp" + tag + "; ip -n " + hub_ns + " link set vhp" +
        tag + " up; ip -n " + hub_ns + " link set lo up; ip -n " + node_ns +
        " addr add 10.77.2.2/24 dev vnp" + tag + "; ip -n " + node_ns + " link set vnp" + tag +
        " up; ip -n " + node_ns + " link set lo up";
    struct Cleanup {
        std::string a, b;
        ~Cleanup() {
            std::system(
                ("ip netns del " + a + " 2>/dev/null; ip netns del " + b + " 2>/dev/null").c_str());
        }
    } cleanup{hub_ns, node_ns};
    if (std::system(("bash -c '" + setup + "' >/dev/null 2>&1").c_str()) != 0)
        GTEST_SKIP() << "cannot create network namespaces and veth pairs here (ip netns)";
    const HubPort port;
    const fs::path dir = temp_root();
    fs::remove_all(dir / "rec_ns");
    const std::string rig = rig_of(2);
    const std::string p = std::to_string(port.number);
    start(dir, "hub_ns",
          "ip netns exec " + hub_ns + " $BIN/rgbd-capture --rig " + rig +
              " -o rec_ns --listen tcp://10.77.1.2:" + p +
              " --exit-after-bye --probes 8 --latency-ms 1000 --metrics hub_ns.json");
    start(dir, "proxy_ns",
          "$BIN/rgbd_test_loss_proxy --front tcp://10.77.2.1:" + p +
              " --back tcp://10.77.1.2:" + p + " --delay-ms 200 --loss 0.1 --seconds 90");
    const int frames = 150;
    for (int s = 0; s < 2; ++s)
        start(dir, "node_ns_" + std::to_string(s),
              "ip netns exec " + node_ns + " $BIN/rgbd-node --sensor playback:synth#" + id(s) +
                  " --loop --frames " + std::to_string(frames) + " --hub tcp://10.77.2.1:" + p +
                  " --clock-offset-ms " + std::to_string(s ? -380 : 440) + " --clock-drift-ppm " +
                  std::to_string(s ? 45 : -30) + " --truth truth_ns_" + std::to_string(s) +
                  ".csv --metrics node_ns_" + std::to_string(s) + ".json");
    for (int s = 0; s < 2; ++s)
        ASSERT_EQ(wait_for(dir, "node_ns_" + std::to_string(s), 90), 0)
            << slurp(dir / ("node_ns_" + std::to_string(s) + ".err"));
    const int hub_code = wait_for(dir, "hub_ns", 30);
    ::kill(pid_of(dir, "proxy_ns"), SIGTERM);
    ASSERT_EQ(hub_code, 0) << slurp(dir / "hub_ns.err");
    const json hub = read_json(dir / "hub_ns.json");
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec_ns");
    double worst_frame_ns = 0, worst_bound_ns = 0, worst_rtt_ns = 0;
    for (int s = 0; s < 2; ++s) {
        const json node = read_json(dir / ("node_ns_" + std::to_string(s) + ".json"));
        const auto truth = read_truth(dir / ("truth_ns_" + std::to_string(s) + ".csv"));
        const auto& recorded = cap.frames.at(id(s));
        // About 10% of the frames are lost on the way; every frame that arrives is recorded.
        EXPECT_GT(recorded.size(), truth.size() * 3 / 4) << id(s);
        EXPECT_LT(recorded.size(), truth.size()) << id(s);
        const json& clock = hub["sensors"][id(s)]["clock"];
        const double at = clock["at_hub_ns"].get<double>();
        const double true_offset =
            node["clock_offset_ns"].get<double>() + node["clock_drift_ppm"].get<double>() * 1e-6 *
                                                        (at - node["clock_epoch_ns"].get<double>());
        // The proxy holds every probe and reply 200 ms: only the round trip beyond 400 ms is
        // unknown delay (the 1 ms target holds unless the machine adds more than ~1.3 ms).
        const double bound = clock_error_bound_ns(clock, 200e6);
        worst_bound_ns = std::max(worst_bound_ns, bound);
        worst_rtt_ns = std::max(worst_rtt_ns, clock["max_round_trip_ns"].get<double>());
        EXPECT_LT(std::abs(clock["offset_ns"].get<double>() - true_offset), bound)
            << id(s) << ", probe round trips up to " << clock["max_round_trip_ns"] << " ns";
        // Each recorded frame is the sent frame whose true instant it carries, within 1 ms
        // (or what the round trips allow), and its depth is the source's.
        std::size_t t = 0;
        for (const auto& f : recorded) {
            while (t < truth.size() && truth[t].true_ns < f.time_ns - 16'000'000) ++t;
            ASSERT_LT(t, truth.size());
            const double e = std::abs(static_cast<double>(f.time_ns - truth[t].true_ns));
            worst_frame_ns = std::max(worst_frame_ns, e);
            ASSERT_LT(e, bound) << id(s) << ", probe round trips up to "
                                << clock["max_round_trip_ns"] << " ns";
            const cv::Mat d =
                cv::imread((dir / "rec_ns" / id(s) / f.depth).string(), cv::IMREAD_UNCHANGED);
            ASSERT_EQ(cv::norm(d, source_depth(id(s), truth[t].position), cv::NORM_INF), 0.0);
        }
    }
    EXPECT_GT(hub["missing_slots"].get<int>(), 0);
    EXPECT_LE(hub["max_spread_ns"].get<double>(), hub["tolerance_ns"].get<double>());
    std::cout << "[ capture ] between namespaces: worst frame time error " << worst_frame_ns / 1e3
              << " us (bound " << worst_bound_ns / 1e3 << " us, probe round trips up to "
              << worst_rtt_ns / 1e3 << " us)\n";
}

}  // namespace

namespace {

/// The documents of a view stream file, each written back without its rgbd:history lines
/// (which name the tool that wrote it), for byte comparison.
std::vector<std::pair<rgbd::ViewInfo, std::string>> stream_documents(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    rgbd::io::PlyStreamReader reader(in, path.string());
    std::vector<std::pair<rgbd::ViewInfo, std::string>> out;
    rgbd::io::Document document;
    while (reader.next(document)) {
        document.cloud.view.history.clear();
        std::ostringstream bytes;
        rgbd::io::write_document(bytes, document);
        out.emplace_back(document.cloud.view, bytes.str());
    }
    return out;
}

}  // namespace

TEST_F(RgbdCapture, LiveStreamGivesTheViewsRgbdCloudMakesFromTheRecording) {
    const HubSession session("live");
    const fs::path dir = temp_root();
    fs::remove(dir / "live.ply");
    session.record(rig_of(3), "rec_live",
                   "--live live.ply --exit-after-bye --latency-ms 300 --probe-interval-ms 500 "
                   "--metrics hub_live.json");
    for (int s = 0; s < 3; ++s)
        session.start_node(s, "--frames 45 --clock-offset-ms " + std::to_string(200 * s - 200));
    ASSERT_TRUE(session.nodes_succeed(3, 60));
    ASSERT_TRUE(session.hub_exits(0, 30));

    const json hub = read_json(dir / "hub_live.json");
    const json& live = hub["live"];
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec_live");
    EXPECT_EQ(cap.frames.at(id(0)).size(), 45u) << "streaming does not cost the recording";
    const auto views = stream_documents(dir / "live.ply");
    // How many sets the stream thread gets out depends on the machine's load (a slow reader
    // gets fewer, the rest are skipped and counted); three are enough for first, middle, last.
    ASSERT_GE(live["sets_emitted"].get<int>(), 3) << live.dump();
    EXPECT_EQ(views.size(), 3 * live["sets_emitted"].get<std::size_t>());
    EXPECT_EQ(live["views"].get<std::size_t>(), views.size());
    std::int64_t complete = 0;
    for (const auto& set : cap.framesets)
        complete += std::count(set.frames.begin(), set.frames.end(), -1) == 0;
    EXPECT_EQ(live["sets_emitted"].get<std::int64_t>() + live["sets_skipped"].get<std::int64_t>(),
              complete);

    // Each streamed set is the recording's frame set with the same frames, and its views are
    // byte for byte what rgbd-cloud makes of that set (first, middle and last set).
    const std::size_t sets = views.size() / 3;
    for (std::size_t k : {std::size_t{0}, sets / 2, sets - 1}) {
        std::optional<std::size_t> match;
        for (std::size_t f = 0; f < cap.framesets.size() && !match; ++f) {
            bool same = true;
            for (std::size_t s = 0; s < 3; ++s)
                same = same && views[3 * k + s].first.sensor == id(static_cast<int>(s)) &&
                       views[3 * k + s].first.frame_index == cap.framesets[f].frames[s];
            if (same) match = f;
        }
        ASSERT_TRUE(match) << "streamed set " << k << " is not a recorded frame set";
        const std::string out = "cloud_live_" + std::to_string(k) + ".ply";
        Outcome r =
            run("$BIN/rgbd-cloud rec_live --frameset " + std::to_string(*match) + " -o " + out);
        ASSERT_EQ(r.code, 0) << r.err;
        const auto expected = stream_documents(dir / out);
        ASSERT_EQ(expected.size(), 3u);
        for (std::size_t s = 0; s < 3; ++s) {
            EXPECT_EQ(views[3 * k + s].second, expected[s].second)
                << "set " << k << " view " << s << " differs from rgbd-cloud's";
            EXPECT_TRUE(fs::exists(dir / views[3 * k + s].first.source))
                << "the view names its recorded depth image: " << views[3 * k + s].first.source;
        }
    }
}

TEST_F(RgbdCapture, LiveSnapshotWithoutRecordingAndAReaderThatGoesAway) {
    const HubSession snapshot("snap");
    const fs::path dir = temp_root();
    const std::string rig = rig_of(2);
    // One frame set to stdout, nothing recorded: a snapshot for a pipeline.
    snapshot.start_hub("--rig " + rig +
                       " --live - --live-sets 1 --latency-ms 300 --metrics hub_snap.json");
    snapshot.start_nodes(2, "--frames 60");
    ASSERT_TRUE(snapshot.hub_exits(0, 30));
    for (int s = 0; s < 2; ++s) wait_for(dir, snapshot.node(s), 30);
    const json snap = read_json(dir / "hub_snap.json");
    EXPECT_EQ(snap["stop_reason"], "live sets streamed");
    EXPECT_EQ(snap["live"]["sets_emitted"], 1);
    const auto views = stream_documents(dir / "hub_snap.out");
    ASSERT_EQ(views.size(), 2u);
    EXPECT_EQ(views[0].first.sensor, id(0));
    EXPECT_EQ(views[1].first.sensor, id(1));
    EXPECT_TRUE(views[0].first.source.empty()) << "nothing recorded, no source to name";
    EXPECT_TRUE(views[0].first.world_from_sensor.has_value());

    // The reader of the live stream exits after a few bytes: the hub records on.
    const HubSession closed_reader("closed");
    closed_reader.record(rig, "rec_closed",
                         "--live - --exit-after-bye --latency-ms 300 --metrics hub_closed.json "
                         "| head -c 100 >/dev/null");
    closed_reader.start_nodes(2, "--frames 45");
    ASSERT_TRUE(closed_reader.nodes_succeed(2, 60));
    ASSERT_TRUE(closed_reader.hub_exits(0, 30));
    const json closed = read_json(dir / "hub_closed.json");
    EXPECT_TRUE(closed["live"]["reader_closed"].get<bool>());
    EXPECT_EQ(closed["stop_reason"], "all nodes done");
    const rgbd::io::Capture cap = rgbd::io::open_capture(dir / "rec_closed");
    EXPECT_EQ(cap.frames.at(id(1)).size(), 45u);
}

TEST_F(RgbdCapture, LiveOptionErrors) {
    EXPECT_TRUE(is_usage_error(run("$BIN/rgbd-capture --rig synth/rig.json"), "--live"));
    EXPECT_TRUE(is_usage_error(run("$BIN/rgbd-capture --rig synth/rig.json -o y --live-sets 2"),
                               "--live-sets needs --live"));
    EXPECT_TRUE(is_usage_error(run("$BIN/rgbd-capture --rig synth/rig.json --live - --metrics -")));
    EXPECT_TRUE(
        is_usage_error(run("$BIN/rgbd-capture --rig synth/rig.json --live - --live-sets -1")));
    const Outcome r =
        run("$BIN/rgbd-capture --rig synth/rig.json --live no_such_dir/live.ply --listen "
            "tcp://127.0.0.1:" +
            std::to_string(free_port()));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("no_such_dir"), std::string::npos) << r.err;
    EXPECT_EQ(rgbd::test::line_count(r.err), 1) << r.err;
    EXPECT_FALSE(fs::exists(temp_root() / "y"));
}
