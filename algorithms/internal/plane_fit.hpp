// Least-squares plane through points (the normal is the covariance's smallest principal axis)
// and RANSAC for the plane near a direction (Fischler and Bolles 1981), shared by the segment
// stage's ground and stand finders. Internal to algorithms/.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "toolkit/random.hpp"

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

/// RANSAC for the plane n . p + d = 0 with n within acos(cos_tilt) of the unit `up` (n on its
/// side) that holds the most of `points` within `inlier` (metres): `iterations` hypotheses
/// through 3 of the points drawn by SplitMix64 from `seed`. Returns the number of inliers of the
/// best plane (n, d); fewer than 3 (or fewer than 3 points) means none was found.
inline std::size_t ransac_plane(const std::vector<Eigen::Vector3d>& points,
                                const Eigen::Vector3d& up, double cos_tilt, double inlier,
                                int iterations, std::uint64_t seed, Eigen::Vector3d& best_n,
                                double& best_d) {
    std::size_t best_score = 0;
    if (points.size() < 3) return 0;
    std::uint64_t state = seed;
    for (int it = 0; it < iterations; ++it) {
        const auto& a = points[splitmix64_next(state) % points.size()];
        const auto& b = points[splitmix64_next(state) % points.size()];
        const auto& c = points[splitmix64_next(state) % points.size()];
        Eigen::Vector3d n = (b - a).cross(c - a);
        if (n.norm() < 1e-12) continue;
        n.normalize();
        if (n.dot(up) < 0) n = -n;
        if (n.dot(up) < cos_tilt) continue;
        const double d = -n.dot(a);
        std::size_t score = 0;
        for (const auto& q : points) score += std::abs(n.dot(q) + d) <= inlier;
        if (score > best_score) best_score = score, best_n = n, best_d = d;
    }
    return best_score;
}

}  // namespace rgbd::internal
