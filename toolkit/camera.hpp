// Pinhole camera model with optional Brown-Conrady distortion (OpenCV coefficient order
// k1 k2 p1 p2 k3). Camera frame: x right, y down, z forward; pixel (0,0) is the centre of
// the top-left pixel. See docs/formats.md (rig.json) and docs/algorithms.md §2.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace rgbd {

/// Lens distortion. `model` is "none" or "brown" (coefficients k1 k2 p1 p2 k3; missing
/// trailing coefficients are zero).
struct Distortion {
    std::string model = "none";
    std::vector<double> coeffs;

    bool is_none() const;
    /// Throws InputError for an unknown model, too many or non-finite coefficients.
    void check() const;
    /// Distorts normalised coordinates (x, y) = (X/Z, Y/Z).
    Eigen::Vector2d distort(const Eigen::Vector2d& xy) const;
    /// Inverse of distort(), by fixed-point iteration (as OpenCV's undistortPoints).
    Eigen::Vector2d undistort(const Eigen::Vector2d& xy_distorted) const;
};

/// Intrinsics of one camera (depth or colour), in pixels.
struct PinholeIntrinsics {
    int width = 0;   ///< image width in pixels
    int height = 0;  ///< image height in pixels
    double fx = 0, fy = 0, cx = 0, cy = 0;
    Distortion distortion = {};  ///< none unless set

    /// Throws InputError when sizes or focal lengths are not positive or values are not finite.
    void check() const;
    /// Projects a camera-frame point (z > 0) to pixel coordinates, distortion applied.
    Eigen::Vector2d project(const Eigen::Vector3d& p_camera) const;
    /// Back-projects pixel (u, v) at depth z (metres) to a camera-frame point.
    Eigen::Vector3d unproject(double u, double v, double z) const;
    /// True when the pixel coordinate lies inside the image (pixel centres at integers).
    bool contains(const Eigen::Vector2d& uv) const {
        return uv.x() > -0.5 && uv.y() > -0.5 && uv.x() < width - 0.5 && uv.y() < height - 0.5;
    }
    bool operator==(const PinholeIntrinsics& o) const;
};

}  // namespace rgbd
