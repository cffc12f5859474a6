// Least-squares plane through points (the normal is the covariance's smallest principal axis),
// shared by the segment stage's ground and stand finders. Internal to algorithms/.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <vector>

namespace rgbd::internal {

/// Fits n . p + d = 0 (unit n on the side of `up`) to `points`; `rms`, when given, receives the
/// RMS distance of the points to the plane (metres). Returns false for fewer than 3 points.
inline bool fit_plane(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& up,
                      Eigen::Vector3d& n, double& d, double* rms = nullptr) {
    if (points.size() < 3) return false;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : points) mean += p;
    mean /= static_cast<double>(points.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : points) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    n = eig.eigenvectors().col(0).normalized();
    if (n.dot(up) < 0) n = -n;
    d = -n.dot(mean);
    if (rms) *rms = std::sqrt(std::max(0.0, eig.eigenvalues()(0)) / points.size());
    return true;
}

}  // namespace rgbd::internal
