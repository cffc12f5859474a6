// Least-squares plane through points (the normal is the covariance's smallest principal axis)
// and RANSAC for the plane near a direction (Fischler and Bolles 1981), shared by the segment
// stage's ground and stand finders. Internal to algorithms/.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstddef>
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

/// Points by coordinate (structure of arrays), with their normals or none (nx null): what
/// count_plane_votes() scores a plane on.
struct PlaneVoteInput {
    const double *px = nullptr, *py = nullptr, *pz = nullptr;
    const double *nx = nullptr, *ny = nullptr, *nz = nullptr;
    std::size_t m = 0;
};

/// The number of the points of `in` that vote for the plane n . p + d = 0 (unit n): within
/// `band` of it (|n . p + d| <= band, metres) and, with normals, facing it (|n . normal| >=
/// cos_tilt). The same IEEE operations in the same order as Eigen's n.dot(p) + d, 4 points at a
/// time with AVX2 where the CPU has it, 2 with SSE2: the count of the scalar loop.
std::size_t count_plane_votes(const PlaneVoteInput& in, const Eigen::Vector3d& n, double d,
                              double band, double cos_tilt);

/// RANSAC for the plane n . p + d = 0 with n within acos(cos_tilt) of the unit `up` (n on its
/// side) that holds the most of `points` within `inlier` (metres): `iterations` hypotheses
/// through 3 of the points drawn by SplitMix64 from `seed`, each scored on the points by
/// coordinate (count_plane_votes). Returns the number of inliers of the best plane (n, d);
/// fewer than 3 (or fewer than 3 points) means none was found.
inline std::size_t ransac_plane(const std::vector<Eigen::Vector3d>& points,
                                const Eigen::Vector3d& up, double cos_tilt, double inlier,
                                int iterations, std::uint64_t seed, Eigen::Vector3d& best_n,
                                double& best_d) {
    std::size_t best_score = 0;
    if (points.size() < 3) return 0;
    const std::size_t m = points.size();
    std::vector<double> soa(3 * m);
    for (std::size_t j = 0; j < m; ++j)
        soa[j] = points[j].x(), soa[m + j] = points[j].y(), soa[2 * m + j] = points[j].z();
    PlaneVoteInput in;
    in.px = soa.data(), in.py = in.px + m, in.pz = in.py + m, in.m = m;
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
        const std::size_t score = count_plane_votes(in, n, d, inlier, -1.0);
        if (score > best_score) best_score = score, best_n = n, best_d = d;
    }
    return best_score;
}

}  // namespace rgbd::internal
