#include "algorithms/denoise/density_camera.hpp"

#include <algorithm>
#include <limits>

namespace rgbd::denoise::detail {

bool surely_occluded(const Camera& c, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                     NoiseModel noise_model, double tan_max) {
    if (!c.undistorted || c.bw == 0) return false;
    const Eigen::Vector3d centre = c.rotation * (0.5 * (lo + hi)) + c.translation;
    const Eigen::Vector3d half = c.rotation.cwiseAbs() * (0.5 * (hi - lo));
    const Eigen::Vector3d qlo = centre - half, qhi = centre + half;
    if (!(qlo.z() > 1e-3)) return false;
    const double xz0 = std::min(qlo.x() / qlo.z(), qlo.x() / qhi.z()),
                 xz1 = std::max(qhi.x() / qlo.z(), qhi.x() / qhi.z()),
                 yz0 = std::min(qlo.y() / qlo.z(), qlo.y() / qhi.z()),
                 yz1 = std::max(qhi.y() / qlo.z(), qhi.y() / qhi.z());
    const PinholeIntrinsics& k = c.intrinsics;
    // Pixel (col, row) = (int(u + 0.5), int(v + 0.5)) of every point of the box.
    constexpr double kPx = 1e-6;
    const double u0 = k.fx * xz0 + k.cx + 0.5 - kPx, u1 = k.fx * xz1 + k.cx + 0.5 + kPx;
    const double v0 = k.fy * yz0 + k.cy + 0.5 - kPx, v1 = k.fy * yz1 + k.cy + 0.5 + kPx;
    if (!(u0 >= double(c.x0) && v0 >= double(c.y0) && u1 < double(c.x0 + c.bw) &&
          v1 < double(c.y0 + c.bh)))
        return false;  // a centre pixel outside the map's box (or outside the image)
    const int col0 = int(u0), col1 = int(u1), row0 = int(v0), row1 = int(v1);
    const double limit = qlo.z() -
                         std::max(c.occlusion_tolerance(qlo.z(), noise_model, tan_max),
                                  c.occlusion_tolerance(qhi.z(), noise_model, tan_max)) -
                         1e-7;
    // Centre pixels: a return nearer than the limit; the rest of each 3 x 3 window: that or none.
    for (int rr = std::max(row0 - 1, c.y0); rr <= std::min(row1 + 1, c.y0 + c.bh - 1); ++rr) {
        const float* line = c.depth.data() + std::size_t(rr - c.y0) * c.bw;
        const bool centre_row = rr >= row0 && rr <= row1;
        for (int cc = std::max(col0 - 1, c.x0); cc <= std::min(col1 + 1, c.x0 + c.bw - 1); ++cc) {
            const double d = line[cc - c.x0];
            if (d < limit) continue;
            if (centre_row && cc >= col0 && cc <= col1) return false;
            if (d != std::numeric_limits<double>::infinity()) return false;
        }
    }
    return true;
}

}  // namespace rgbd::denoise::detail
