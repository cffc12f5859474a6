// One rgbd-capture hub and its rgbd-node processes in the capture contract tests, started in
// the background in the scratch folder on one free port, and the checks of how they ended.
#pragma once

#include <gtest/gtest.h>
#include <signal.h>

#include <string>

#include "tests/cli/hub_port.hpp"
#include "tests/support/capture_harness.hpp"

namespace rgbd::test::capture {

/// The hub "hub_<tag>" and the nodes "node_<tag>_<s>" of one session, started with start() in
/// temp_root() (their .pid, .rc, .out and .err files carry those names).
class HubSession {
public:
    explicit HubSession(std::string tag) : tag_(std::move(tag)) {}

    const HubPort port;
    const fs::path dir = temp_root();

    std::string hub() const { return "hub_" + tag_; }
    std::string node(int s) const { return "node_" + tag_ + "_" + std::to_string(s); }

    /// Starts "$BIN/rgbd-capture --listen ... ARGS" (ARGS may end in a pipe).
    void start_hub(const std::string& args) const {
        start(dir, hub(), "$BIN/rgbd-capture" + port.listen() + " " + args);
    }
    /// Starts the hub recording the rig file `rig` into the folder `recording` of the scratch
    /// folder, removed first (a recording of an earlier run would make the hub refuse it):
    /// "$BIN/rgbd-capture --listen ... --rig RIG -o RECORDING ARGS" (ARGS may end in a pipe).
    void record(const std::string& rig, const std::string& recording,
                const std::string& args = "") const {
        fs::remove_all(dir / recording);
        start_hub("--rig " + rig + " -o " + recording + (args.empty() ? "" : " " + args));
    }
    /// Starts node s, "$BIN/rgbd-node --hub ... --sensor playback:synth#k2-S --loop ARGS": sensor s
    /// of the synthetic capture (the fixture's id(s)) replayed in a loop.
    void start_node(int s, const std::string& args) const {
        start(dir, node(s),
              "$BIN/rgbd-node" + port.hub() + " --sensor playback:synth#k2-" + std::to_string(s) +
                  " --loop " + args);
    }
    /// Starts nodes 0 to n - 1 with the same ARGS.
    void start_nodes(int n, const std::string& args) const {
        for (int s = 0; s < n; ++s) start_node(s, args);
    }

    /// Whether the hub ends within `timeout_s` with exit code `code`; else its code and stderr.
    ::testing::AssertionResult hub_exits(int code, double timeout_s) const {
        return exits(hub(), code, timeout_s);
    }
    /// Whether nodes 0 to n - 1 each end with exit code 0 within `timeout_s`; else the first
    /// that did not, with its code and stderr.
    ::testing::AssertionResult nodes_succeed(int n, double timeout_s) const {
        for (int s = 0; s < n; ++s)
            if (auto r = exits(node(s), 0, timeout_s); !r) return r;
        return ::testing::AssertionSuccess();
    }
    /// Sends SIGTERM to nodes 0 to n - 1, then waits up to `timeout_s` for each to end.
    void stop_nodes(int n, double timeout_s) const {
        for (int s = 0; s < n; ++s) ::kill(pid_of(dir, node(s)), SIGTERM);
        for (int s = 0; s < n; ++s) wait_for(dir, node(s), timeout_s);
    }

private:
    ::testing::AssertionResult exits(const std::string& name, int code, double timeout_s) const {
        const int got = wait_for(dir, name, timeout_s);
        if (got == code) return ::testing::AssertionSuccess();
        return ::testing::AssertionFailure() << name << " ended with " << got << " (expected "
                                             << code << ", -1: still running after " << timeout_s
                                             << " s); stderr: " << slurp(dir / (name + ".err"));
    }
    std::string tag_;
};

}  // namespace rgbd::test::capture
