#include "toolkit/camera.hpp"

#include <cmath>

#include "toolkit/error.hpp"

namespace rgbd {

bool Distortion::is_none() const {
    if (model == "none") return true;
    for (double c : coeffs)
        if (c != 0.0) return false;
    return true;
}

void Distortion::check() const {
    RGBD_CHECK(model == "none" || model == "brown",
               "unknown distortion model '" + model + "' (expected none or brown)");
    RGBD_CHECK(coeffs.size() <= 5,
               "brown distortion takes at most 5 coefficients (k1 k2 p1 p2 k3)");
    for (double c : coeffs) RGBD_CHECK(std::isfinite(c), "distortion coefficient is not finite");
}

namespace {
double coeff(const std::vector<double>& c, std::size_t i) { return i < c.size() ? c[i] : 0.0; }
}  // namespace

Eigen::Vector2d Distortion::distort(const Eigen::Vector2d& xy) const {
    if (model == "none" || coeffs.empty()) return xy;
    const double k1 = coeff(coeffs, 0), k2 = coeff(coeffs, 1), p1 = coeff(coeffs, 2),
                 p2 = coeff(coeffs, 3), k3 = coeff(coeffs, 4);
    const double x = xy.x(), y = xy.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

Eigen::Vector2d Distortion::undistort(const Eigen::Vector2d& xy_distorted) const {
    if (model == "none" || coeffs.empty()) return xy_distorted;
    Eigen::Vector2d xy = xy_distorted;
    for (int iteration = 0; iteration < 20; ++iteration) {
        const Eigen::Vector2d error = distort(xy) - xy_distorted;
        xy -= error;
        if (error.squaredNorm() < 1e-24) break;
    }
    return xy;
}

void PinholeIntrinsics::check() const {
    RGBD_CHECK(width > 0 && height > 0, "camera size must be positive");
    RGBD_CHECK(width <= 100000 && height <= 100000, "camera size is absurd");
    RGBD_CHECK(std::isfinite(fx) && std::isfinite(fy) && fx > 0 && fy > 0,
               "focal lengths must be positive and finite");
    RGBD_CHECK(std::isfinite(cx) && std::isfinite(cy), "principal point must be finite");
    distortion.check();
}

Eigen::Vector2d PinholeIntrinsics::project(const Eigen::Vector3d& p) const {
    const Eigen::Vector2d xy = distortion.distort({p.x() / p.z(), p.y() / p.z()});
    return {fx * xy.x() + cx, fy * xy.y() + cy};
}

Eigen::Vector3d PinholeIntrinsics::unproject(double u, double v, double z) const {
    const Eigen::Vector2d xy = distortion.undistort({(u - cx) / fx, (v - cy) / fy});
    return {xy.x() * z, xy.y() * z, z};
}

bool PinholeIntrinsics::operator==(const PinholeIntrinsics& o) const {
    return width == o.width && height == o.height && fx == o.fx && fy == o.fy && cx == o.cx &&
           cy == o.cy && distortion.model == o.distortion.model &&
           distortion.coeffs == o.distortion.coeffs;
}

}  // namespace rgbd
