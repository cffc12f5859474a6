// Small shared pieces of the point-to-plane ICP solvers (algorithms/registration/): robust
// IRLS weights and the rigid update from a linearised (omega, t) step. Internal to algorithms/.
#pragma once

#include <Eigen/Geometry>
#include <cmath>

#include "toolkit/pose.hpp"

namespace rgbd::internal {

/// IRLS weight of a residual r for kernel 0 = none, 1 = Huber, 2 = Tukey, scale k > 0.
inline double robust_weight(int kernel, double r, double k) {
    const double a = std::abs(r);
    switch (kernel) {
        case 1:
            return a <= k ? 1.0 : k / a;
        case 2: {
            if (a >= k) return 0.0;
            const double u = 1.0 - (a / k) * (a / k);
            return u * u;
        }
        default:
            return 1.0;
    }
}

/// Rigid motion for the linearised step x = (omega, t) taken about the centre c:
/// p' = R(omega) (p - c) + c + t, with R the exact rotation of angle |omega| about omega.
inline Pose rigid_update(const Eigen::Matrix<double, 6, 1>& x, const Eigen::Vector3d& c) {
    const Eigen::Vector3d omega = x.head<3>();
    const double angle = omega.norm();
    Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
    if (angle > 0) r = Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
    Pose d = Pose::Identity();
    d.linear() = r;
    d.translation() = c + x.tail<3>() - r * c;
    return d;
}

}  // namespace rgbd::internal
