// Progress reporting for long algorithms, like CGAL's `callback` named parameter.
#pragma once

#include <functional>

namespace rgbd {

/// Called with the fraction done in [0, 1]; return false to cancel. An empty function is allowed.
using Progress = std::function<bool(double)>;

/// Calls `progress` if set; returns false when the caller asked to cancel.
inline bool report_progress(const Progress& progress, double fraction) {
    return !progress || progress(fraction);
}

}  // namespace rgbd
