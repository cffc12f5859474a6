// The local port of one rgbd-capture hub session in the capture contract tests, with the
// arguments that put the hub on it and point the nodes at it.
#pragma once

#include <string>

#include "tests/support/capture_harness.hpp"

namespace rgbd::test::capture {

/// A free local port for one hub (its control socket is the next port, as rgbd-capture uses).
struct HubPort {
    int number = free_port();
    /// " --listen tcp://127.0.0.1:PORT", rgbd-capture's argument.
    std::string listen() const { return " --listen tcp://127.0.0.1:" + std::to_string(number); }
    /// " --hub tcp://127.0.0.1:PORT", rgbd-node's argument.
    std::string hub() const { return " --hub tcp://127.0.0.1:" + std::to_string(number); }
};

}  // namespace rgbd::test::capture
