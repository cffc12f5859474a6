// The cluster pass of the density-based cleaning (docs/algorithms.md §8): small detached
// clusters of the survivors are dropped. Internal to algorithms/denoise (not installed).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "toolkit/report.hpp"

namespace rgbd::denoise::detail {

/// Outcome of the cluster pass.
struct ClusterCount {
    std::size_t removed = 0;   ///< points flagged
    std::size_t clusters = 0;  ///< components of the survivors
};

/// The cluster pass over the survivors (outlier[i] == 0; with `only`, those with only[i] != 0):
/// links points within eps (a multiple of the spacing, recorded as cluster_eps_m) and flags
/// every component but the largest (ties: the one with the earliest point) that holds less than
/// min_cluster_fraction of them.
ClusterCount flag_small_clusters(const std::vector<Eigen::Vector3d>& world, double eps,
                                 double min_cluster_fraction, std::vector<std::uint8_t>& outlier,
                                 Report& report, const std::vector<std::uint8_t>* only = nullptr);

}  // namespace rgbd::denoise::detail
