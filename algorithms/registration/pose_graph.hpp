// Pose-graph optimisation of a ring or sequence of views (docs/algorithms.md §6): nodes are
// world_from_view poses, edges are measured relative poses with information matrices from the
// pairwise alignment; Gauss-Newton / Levenberg-Marquardt on SE(3) with one node fixed (the
// gauge), then edges that disagree with the optimised ring are pruned and the rest re-solved.
// Sources: Lu and Milios 1997 (globally consistent range scan alignment); Grisetti et al. 2010
// "A tutorial on graph-based SLAM"; Choi, Zhou and Koltun, CVPR 2015 (Open3D
// global_optimization: information from correspondences, pruning of inconsistent edges).
// See also: global_registration.hpp, icp.hpp (align_views runs this between the pairwise and
// the joint stages).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "toolkit/pose.hpp"

namespace rgbd::registration {

struct PoseGraphEdge {
    std::size_t source = 0;  ///< node j
    std::size_t target = 0;  ///< node i
    /// Measured target_from_source = X_i^-1 X_j.
    Pose target_from_source = Pose::Identity();
    /// Information of the source frame's pose (rotation first), e.g. sum of G^T G over matched
    /// points with G = [-[p]x, I], p in the source frame.
    Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();
    bool active = true;  ///< pruned edges are kept but inactive
};

struct PoseGraphOptions {
    std::size_t fixed_node = 0;
    int max_iterations = 50;
    /// After a solve, the edge whose residual most exceeds these (rotation, or translation of
    /// the residual motion) is deactivated when the graph stays connected without it, and the
    /// graph is solved again, until no active edge exceeds them.
    double prune_rotation_deg = 2.0;
    double prune_translation_m = 0.01;
    void check() const;
};

struct EdgeResidual {
    double rotation_deg = 0.0;
    double translation_m = 0.0;  ///< |residual translation|
};

struct PoseGraphResult {
    std::vector<Pose> poses;              ///< optimised world_from_view, same order
    std::vector<EdgeResidual> residuals;  ///< per edge, at the optimum (pruned ones too)
    std::vector<bool> active;             ///< per edge, after pruning
    std::vector<bool> connected;          ///< per node: reached from the fixed node
    int iterations = 0;
    double initial_cost = 0.0, final_cost = 0.0;
};

/// Optimises `initial` poses (nodes not reached from the fixed node by active edges keep their
/// initial pose and are marked not connected). Deterministic. Throws InputError on bad indices
/// or non-finite input.
PoseGraphResult optimise_pose_graph(const std::vector<Pose>& initial,
                                    const std::vector<PoseGraphEdge>& edges,
                                    const PoseGraphOptions& options);

/// Residual of one edge at the given poses: Z^-1 X_i^-1 X_j as rotation angle and translation.
EdgeResidual edge_residual(const std::vector<Pose>& poses, const PoseGraphEdge& edge);

}  // namespace rgbd::registration
