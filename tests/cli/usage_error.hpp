// A check shared by the CLI contract tests: a command line is refused as a usage error.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "tests/support/tool_runner.hpp"

namespace rgbd::test {

/// Whether the run `r` is a usage error (exit code 2) whose stderr contains `says` (any
/// message when empty). On failure, the exit code and stderr are part of the message.
inline ::testing::AssertionResult is_usage_error(const Outcome& r, const std::string& says = "") {
    if (r.code == 2 && r.err.find(says) != std::string::npos) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure()
           << "exit code " << r.code << " (a usage error is 2)"
           << (says.empty() ? "" : ", expected '" + says + "'") << "; stderr: " << r.err;
}

}  // namespace rgbd::test
