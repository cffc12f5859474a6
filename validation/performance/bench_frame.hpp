// The synthetic frame of the single-view benchmarks (bench_upsample, bench_normals): a Kinect v2
// (512x424 depth, 1920x1080 colour 52 mm aside) seeing a sphere of 0.2 m radius at 1.5 m (about
// the point count of a bust view), random colour.
#pragma once

#include <cmath>
#include <opencv2/core.hpp>

#include "toolkit/rgbd_frame.hpp"

namespace rgbd::bench {

inline RgbdFrame synthetic_sphere_frame() {
    RgbdFrame f;
    f.depth_intrinsics = {512, 424, 365.5, 365.5, 256.0, 212.0, {}};
    f.color_intrinsics = {1920, 1080, 1081.37, 1081.37, 959.5, 539.5, {}};
    f.color_from_depth = Pose::Identity();
    f.color_from_depth.translation() = Eigen::Vector3d(-0.052, 0, 0);
    f.depth = cv::Mat(424, 512, CV_32FC1, cv::Scalar(NAN));
    const Eigen::Vector3d c(0, 0, 1.5);
    const double r = 0.2;
    for (int v = 0; v < 424; ++v)
        for (int u = 0; u < 512; ++u) {
            const Eigen::Vector3d d = f.depth_intrinsics.unproject(u, v, 1.0).normalized();
            const double b = d.dot(c), disc = b * b - (c.squaredNorm() - r * r);
            if (disc > 0) f.depth.at<float>(v, u) = float((b - std::sqrt(disc)) * d.z());
        }
    f.color = cv::Mat(1080, 1920, CV_8UC3);
    cv::randu(f.color, 0, 255);
    return f;
}

}  // namespace rgbd::bench
