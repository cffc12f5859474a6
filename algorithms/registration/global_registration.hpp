// Global (initialisation-free) pairwise registration: FPFH features and RANSAC over feature
// correspondences (docs/algorithms.md §6).
// Sources: Rusu, Blodow and Beetz, ICRA 2009 "Fast Point Feature Histograms (FPFH) for 3D
// registration" (33-bin SPFH/FPFH, the angle triplet of Rusu 2008); Fischler and Bolles 1981
// (RANSAC); pruning of samples by edge-length consistency as in Open3D
// pipelines/registration/Feature.cpp and Registration.cpp (RegistrationRANSACBasedOnFeature-
// Matching, CorrespondenceCheckerBasedOnEdgeLength); Umeyama 1991 (closed-form rigid fit).
// See also: algorithms/registration/icp.hpp (refinement), pose_graph.hpp.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "toolkit/pose.hpp"

namespace rgbd::registration {

/// 33-bin FPFH descriptor (3 x 11 bins: alpha, phi, theta).
using Fpfh = Eigen::Matrix<float, 33, 1>;

/// FPFH of every point; neighbours within `radius` (at most `max_neighbours`). Normals must be
/// unit length. Deterministic, parallel. Points without neighbours get a zero descriptor.
std::vector<Fpfh> compute_fpfh(const std::vector<Eigen::Vector3d>& xyz,
                               const std::vector<Eigen::Vector3d>& normals, double radius,
                               int max_neighbours = 100);

struct RansacOptions {
    int iterations = 50000;         ///< 3-point hypotheses
    double inlier_distance = 0.01;  ///< m, a correspondence agrees within this
    double edge_ratio = 0.9;        ///< sample edges must agree to this ratio
    bool mutual = true;             ///< keep only mutual nearest feature neighbours
    /// When set, hypotheses whose rotation differs from this prior by more than
    /// `max_prior_rotation_deg` are discarded (a rig calibration that is roughly right).
    std::optional<Pose> prior;
    double max_prior_rotation_deg = 30.0;
    std::uint64_t seed = 0;
    void check() const;
};

struct RansacResult {
    Pose target_from_source = Pose::Identity();
    std::size_t inliers = 0;          ///< feature correspondences that agree with the pose
    std::size_t correspondences = 0;  ///< feature correspondences considered
    bool found = false;               ///< some hypothesis had at least 3 inliers
};

/// RANSAC over nearest-feature correspondences source -> target; the best hypothesis (most
/// inliers, then lowest iteration index) is refitted to its inliers. Deterministic for a seed
/// and any thread count. Throws InputError on size mismatches.
RansacResult ransac_feature_match(const std::vector<Eigen::Vector3d>& source_xyz,
                                  const std::vector<Fpfh>& source_features,
                                  const std::vector<Eigen::Vector3d>& target_xyz,
                                  const std::vector<Fpfh>& target_features,
                                  const RansacOptions& options);

}  // namespace rgbd::registration
