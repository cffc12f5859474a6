// Intrinsics of the synthetic organised views of the filter tests: a distortion-free pinhole
// with square pixels and the principal point at the image centre.
#pragma once

#include "toolkit/camera.hpp"

namespace rgbd::test {

inline PinholeIntrinsics centred_pinhole(int width, int height, double focal_px) {
    PinholeIntrinsics k;
    k.width = width;
    k.height = height;
    k.fx = k.fy = focal_px;
    k.cx = width / 2.0;
    k.cy = height / 2.0;
    return k;
}

}  // namespace rgbd::test
