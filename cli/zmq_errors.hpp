// ZeroMQ errors of the networked tools (rgbd-capture, rgbd-node) as the toolkit's errors, so
// that run_tool reports them in one line with exit code 1 (cli/README.md).
#pragma once

#include <string>
#include <zmq.hpp>

#include "cli/common/tool.hpp"
#include "toolkit/error.hpp"

namespace rgbd::cli {

/// Binds `socket` to `endpoint`, the value of the command-line option `option` ("--listen");
/// throws IoError "--listen ENDPOINT: cannot listen: REASON" when ZeroMQ cannot.
inline void listen_on(zmq::socket_t& socket, const std::string& option,
                      const std::string& endpoint) {
    try {
        socket.bind(endpoint);
    } catch (const zmq::error_t& e) {
        throw IoError(option + " " + endpoint + ": cannot listen: " + e.what());
    }
}

/// A tool body that reports a ZeroMQ error escaping `body` as IoError "ZeroMQ: REASON".
inline ToolMain zmq_errors_as_io_errors(void (*body)(Context&)) {
    return [body](Context& ctx) {
        try {
            body(ctx);
        } catch (const zmq::error_t& e) {
            throw IoError(std::string("ZeroMQ: ") + e.what());
        }
    };
}

}  // namespace rgbd::cli
