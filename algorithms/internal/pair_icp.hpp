// Pairwise point-to-plane ICP with an optional colour term on plain arrays, used by the ring
// alignment (align_views: pair edges of the pose graph). Internal to algorithms/.
// Sources: Chen and Medioni 1991 (point-to-plane, linearised); Park, Zhou and Koltun, ICCV 2017
// (coloured ICP: tangent-plane intensity gradients, joint geometric + photometric energy);
// Open3D GetInformationMatrixFromPointClouds (edge information matrix).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/registration/icp.hpp"
#include "toolkit/pose.hpp"

namespace rgbd::internal {

/// One registration copy in its working frame.
struct RegCloud {
    std::vector<Eigen::Vector3d> xyz, normals;
    /// Mean of R, G, B in [0, 1] per point; empty when the view has no colour.
    std::vector<float> intensity;
    /// Tangent-plane intensity gradient per point (1/m), orthogonal to the normal; filled by
    /// compute_intensity_gradients (targets of the colour term).
    std::vector<Eigen::Vector3d> gradient;
    bool oriented = true;  ///< normals point towards a known sensor
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    bool has_colour() const { return !intensity.empty() && intensity.size() == xyz.size(); }
};

/// Park et al.'s linear colour model around every point: d with d.n = 0 minimising
/// sum_k (I_p + d.(proj(p_k) - p) - I_k)^2 over the k nearest neighbours (tree over cloud.xyz).
/// No-op when the cloud has no colour.
void compute_intensity_gradients(RegCloud& cloud, const KdTree& tree, int k);

/// The same gradients from the points' nearest neighbours already known: `neighbours` holds
/// every point's s nearest (nearest first, the point itself among them, point after point, as
/// normals::estimate_normals gives them), of which the first k are taken; the tree answers
/// instead when s is smaller than k or the list does not fit the cloud.
void compute_intensity_gradients(RegCloud& cloud, const KdTree& tree, int k,
                                 const std::vector<std::uint32_t>& neighbours);

struct PairIcpSettings {
    std::vector<double> distances;  ///< coarse-to-fine max correspondence distances (m)
    int max_iterations = 30;        ///< per stage
    int kernel = 2;                 ///< robust_weight kernel (2 = Tukey)
    double kernel_scale = 0.5;      ///< kernel k = kernel_scale * stage distance
    double cos_gate = 0.5;          ///< normal gate (cosine); < -1 disables
    /// Weight of the colour term relative to the geometric one after both residuals are
    /// divided by their noise scales (0 = geometry only).
    double colour_weight = 0.0;
    double geometric_sigma = 0.002;  ///< m, scale of point-to-plane residuals
    double colour_sigma = 0.05;      ///< intensity scale of colour residuals
    double min_motion = 0.0;         ///< m: a stage ends when a step moves no point more
    /// Also end a stage when the relative change of fitness and of inlier RMSE between two
    /// iterations are both below these (Open3D ICPConvergenceCriteria; 0 = off), or when a
    /// step rotates less than min_rotation_rad and translates less than min_translation.
    double relative_fitness = 0.0, relative_rmse = 0.0;
    double min_rotation_rad = -1.0, min_translation = -1.0;  ///< < 0 = off
    /// Coarse stages match every 2^k-th source point (k = stages left, at most 3, at least
    /// ~1000 points); false: all points in every stage.
    bool stride_coarse_stages = true;
};

/// The fit of align_pair (pose, matched pairs, fitness, RMS distances, iterations,
/// convergence; "matched" = within eval_distance, normal gate applied) and what the ring
/// alignment needs besides.
struct PairIcpOutcome : registration::AlignResult {
    double colour_rmse = 0.0;  ///< intensity residual of Park's model over matched pairs
    /// Matched pairs whose colour agrees (|residual| <= 3 colour_sigma); = matched without
    /// the colour term. Scores hypotheses: on a surface that slides, geometry alone prefers
    /// the most overlap, colour prefers the right place.
    std::size_t consistent = 0;
    /// Information of the pose of the source frame: sum over matched pairs of G^T G with
    /// G = [-[p]x, I] and p the source point in its own frame (order: rotation, translation).
    Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

/// Pairwise ICP of `source` onto `target` (target_tree over target.xyz), then an evaluation
/// at `eval_distance`. Deterministic for any thread count.
PairIcpOutcome pair_icp(const RegCloud& source, const RegCloud& target, const KdTree& target_tree,
                        const Pose& initial_target_from_source, const PairIcpSettings& settings,
                        double eval_distance);

}  // namespace rgbd::internal
