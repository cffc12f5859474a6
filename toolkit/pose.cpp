#include "toolkit/pose.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "toolkit/error.hpp"

namespace rgbd {

double rotation_error_deg(const Pose& a, const Pose& b) {
    const Eigen::Matrix3d r = a.linear() * b.linear().transpose();
    const double c = std::clamp((r.trace() - 1.0) / 2.0, -1.0, 1.0);
    return std::acos(c) * 180.0 / M_PI;
}

std::optional<Eigen::Vector3d> sensors_up(const std::vector<Pose>& world_from_sensor,
                                          double min_agreement) {
    if (world_from_sensor.empty()) return std::nullopt;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const Pose& pose : world_from_sensor) sum -= pose.linear().col(1);
    const Eigen::Vector3d mean = sum / static_cast<double>(world_from_sensor.size());
    if (!mean.allFinite() || mean.norm() < std::max(min_agreement, 1e-12)) return std::nullopt;
    return mean.normalized();
}

double translation_error_m(const Pose& a, const Pose& b) {
    return (a.translation() - b.translation()).norm();
}

Pose pose_from_3x4(const std::array<double, 12>& v) {
    for (double x : v) RGBD_CHECK(std::isfinite(x), "pose contains a non-finite number");
    Eigen::Matrix3d r;
    r << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    RGBD_CHECK((r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-4 &&
                   r.determinant() > 0,
               "pose rotation is not a rotation matrix (not orthonormal or a reflection)");
    Pose pose = Pose::Identity();
    pose.linear() = r;
    pose.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
    return orthonormalized(pose);
}

Pose pose_from_4x4(const std::array<double, 16>& v) {
    RGBD_CHECK(std::abs(v[12]) < 1e-9 && std::abs(v[13]) < 1e-9 && std::abs(v[14]) < 1e-9 &&
                   std::abs(v[15] - 1.0) < 1e-9,
               "pose last row must be 0 0 0 1");
    return pose_from_3x4(
        {v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9], v[10], v[11]});
}

std::array<double, 12> pose_to_3x4(const Pose& pose) {
    std::array<double, 12> v{};
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) v[r * 4 + c] = pose.linear()(r, c);
        v[r * 4 + 3] = pose.translation()(r);
    }
    return v;
}

Pose orthonormalized(const Pose& pose) {
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(pose.linear(), Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
    if (r.determinant() < 0) {
        Eigen::Matrix3d u = svd.matrixU();
        u.col(2) *= -1.0;
        r = u * svd.matrixV().transpose();
    }
    Pose out = pose;
    out.linear() = r;
    return out;
}

Pose look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target,
             const Eigen::Vector3d& up) {
    const Eigen::Vector3d d = target - position;
    RGBD_CHECK(d.norm() > 1e-9, "look_at: position and target coincide");
    const Eigen::Vector3d z = d.normalized();
    const Eigen::Vector3d xr = z.cross(up);
    RGBD_CHECK(xr.norm() > 1e-9, "look_at: view direction parallel to up");
    const Eigen::Vector3d x = xr.normalized();
    const Eigen::Vector3d y = z.cross(x);
    Pose p = Pose::Identity();
    p.linear().col(0) = x;
    p.linear().col(1) = y;
    p.linear().col(2) = z;
    p.translation() = position;
    return p;
}

}  // namespace rgbd
