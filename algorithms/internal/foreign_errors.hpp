// The toolkit's errors for exceptions of the libraries it calls: a public function that calls
// into OpenCV or CGAL runs those calls through with_foreign_errors, so what escapes the toolkit
// is an rgbd::Error naming the input, never a cv::Exception or a CGAL::Failure_exception (the
// tools' driver and the fuzz targets rely on that; validation/robustness/README.md).
// Validate inputs first (RGBD_CHECK): this is the net for what validation cannot foresee.
// In algorithms/internal (not installed): it includes CGAL's and OpenCV's headers.
#pragma once

#include <CGAL/assertions.h>

#include <opencv2/core.hpp>
#include <string>
#include <utility>

#include "toolkit/error.hpp"

namespace rgbd::internal {

/// Returns `f()`; a cv::Exception or CGAL::Failure_exception it throws is rethrown as
/// AlgorithmError "<what>: <OpenCV|CGAL> failed: <its message>" (`what` names the input and
/// the step, e.g. "board image of 6 x 32 squares"). rgbd::Error and other exceptions pass
/// through unchanged.
template <typename F>
decltype(auto) with_foreign_errors(const std::string& what, F&& f) {
    try {
        return std::forward<F>(f)();
    } catch (const cv::Exception& e) {
        throw AlgorithmError(what + ": OpenCV failed: " + (e.err.empty() ? e.what() : e.err));
    } catch (const CGAL::Failure_exception& e) {
        throw AlgorithmError(what + ": CGAL failed: " + e.what());
    }
}

}  // namespace rgbd::internal
