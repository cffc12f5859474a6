// Report: what an algorithm resolved, counted and timed, as one JSON object.
// Keys are snake_case with units (`inlier_rmse_m`, `time_s`). Tools merge reports
// into the `--metrics` file (cli/README.md).
#pragma once

#include <chrono>
#include <nlohmann/json.hpp>

namespace rgbd {

using Report = nlohmann::json;

/// Wall-clock stopwatch for `time_s` entries in reports.
class Stopwatch {
public:
    Stopwatch() : start_(std::chrono::steady_clock::now()) {}
    double seconds() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }

private:
    std::chrono::steady_clock::time_point start_;
};

}  // namespace rgbd
