// Stages of align_views (icp.hpp), internal to algorithms/registration: the working copies,
// the pairwise stage with its pose graph (pairwise_stage.cpp, docs/algorithms.md §6) and the joint
// multi-view point-to-plane refinement (joint_refinement.cpp). align_views.cpp runs them in
// order. Not a public header: it exposes the internal kd-tree and ICP arrays.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/pair_icp.hpp"
#include "algorithms/registration/icp.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"

namespace rgbd::registration::detail {

constexpr double kDegToRad = M_PI / 180.0;

/// Working copy of one view: points, normals, intensities and intensity gradients in the frame
/// of its initial pose `initial`, and one kd-tree over them, built once and used by every pair
/// and every joint iteration (the points never move in this frame; only `pose` changes).
struct Working {
    internal::RegCloud reg;
    std::unique_ptr<internal::KdTree> tree;    // over reg.xyz
    Pose initial = Pose::Identity();           // world_from_working at the start
    Pose pose = Pose::Identity();              // current world_from_working
    std::optional<Eigen::Vector3d> direction;  // viewing direction in the world, when known
};

inline std::string view_name(const PointCloud& cloud) {
    return "view " + std::to_string(cloud.view.id);
}

/// Rotation angle (degrees) and translation at point c (working frame of the source) of the
/// motion d.
std::pair<double, double> motion_at(const Pose& d, const Eigen::Vector3d& c);

/// Positions around the cycle when the usable pairs of `list` (in_graph) form exactly one
/// cycle through all nv views; empty otherwise.
std::vector<std::size_t> ring_order(std::size_t nv, const std::vector<PairAlignment>& list);

/// Index in `list` of the pair of views a and b (either order); list.size() when none.
std::size_t pair_index(const std::vector<PairAlignment>& list, std::size_t a, std::size_t b);

/// a_from_b of a pair measurement target_from_source of the pair whose target is `target`.
Pose relative(const Pose& target_from_source, std::size_t target, std::size_t a);

/// Inputs of the pairwise stage that align_views derives from its options and the views.
struct PairwiseInputs {
    const std::vector<const PointCloud*>* measured = nullptr;  // measured points per view
    double voxel = 0.0;                                        // working voxel, m
    int normal_k = 24;
    internal::PairIcpSettings icp;  // coarse-to-fine schedule of the pairs
    double eval_distance = 0.0;     // m, pair fitness distance (2 ŝ)
    double spacing = 0.0;           // ŝ, m
    bool poses_known = false;       // initial poses say something: pairs by direction, bounds
};

/// Pairwise stage (docs/algorithms.md §6): selects the pairs, registers them in parallel (TBB) from
/// the initial relative pose and from an FPFH + RANSAC hypothesis, chooses between candidates
/// on a ring by loop closure, runs the pose graph and sets every connected view's `pose`.
/// Fills result.pairs and result.pairwise_time_s; view_pairs[v] = usable pairs of view v,
/// tied[v] = v is connected to the gauge by usable pairs.
void pairwise_stage(std::vector<Working>& work, const MultiViewOptions& options,
                    const PairwiseInputs& in, MultiViewResult& result, std::vector<int>& view_pairs,
                    std::vector<bool>& tied, const Progress& progress);

/// Settings of the joint refinement (from MultiViewOptions and ŝ).
struct JointSettings {
    int kernel = 2;             // robust_weight kernel
    double kernel_scale = 0.5;  // kernel k = kernel_scale * distance
    double cos_gate = 0.5;      // normal gate (cosine); < -1 disables
    bool oriented = true;       // every view's normals point towards its sensor: signed gate
    bool colour = false;        // Park et al.'s colour term
    double colour_scale = 0.0;  // colour residual weight against geometric ones
    double colour_sigma = 0.05;
    std::size_t fixed_view = 0;  // gauge
    /// Calibration prior (diagonal information: rotation about the centre of the working
    /// points, then translation; in the units of the point-to-plane terms, m²): each free view
    /// is held towards its initial pose with this weight. Zero: no prior (poses unknown).
    Eigen::Matrix<double, 6, 1> prior = Eigen::Matrix<double, 6, 1>::Zero();
};

/// The calibration prior's information (JointSettings::prior) for a rig calibrated to about
/// `rotation_deg` and `translation_m` against point residuals of about `spacing` (ŝ, m):
/// ŝ²/σ² for the three rotation components, then the three translation components.
inline Eigen::Matrix<double, 6, 1> calibration_prior(double spacing, double rotation_deg,
                                                     double translation_m) {
    const double s2 = spacing * spacing, sr = rotation_deg * kDegToRad;
    Eigen::Matrix<double, 6, 1> prior;
    prior.head<3>().setConstant(s2 / (sr * sr));
    prior.tail<3>().setConstant(s2 / (translation_m * translation_m));
    return prior;
}

/// Joint multi-view point-to-plane refinement (Chen-Medioni linearised, all poses at once;
/// Park et al. 2017 colour term). Every working point is matched to the nearest point of its
/// view's partner views (within the distance, then the normal gate): each partner's own
/// kd-tree is queried in that view's working frame, so no tree is rebuilt when poses change,
/// and the cost is linear in the number of views (a bounded number of partners per view). The
/// normal equations are sparse (blocks of partner views) and solved by sparse LDLT.
/// Deterministic for any TBB thread count (per-view sums, combined in view order).
class JointRefinement {
public:
    /// partners[v]: views whose points may match v's points (symmetric, v excluded).
    JointRefinement(std::vector<Working>& work, std::vector<std::vector<std::size_t>> partners,
                    const JointSettings& settings);

    /// Matches every `stride`-th working point of each view (the others stay unmatched: coarse
    /// rounds only steer) at the current poses within dmax (metres).
    void match(double dmax, std::size_t stride = 1);
    /// One Gauss-Newton step from the last match at distance dmax: moves every free view with
    /// at least `min_matches` matched points. Returns the largest displacement of any working
    /// point (m), or nothing when no view could move (nothing to solve, or a singular system).
    /// `moved[v]` counts the steps that moved view v.
    std::optional<double> step(double dmax, std::size_t min_matches, std::vector<int>& moved);
    /// Replaces the calibration prior (JointSettings::prior) of the following steps.
    void set_prior(const Eigen::Matrix<double, 6, 1>& prior) { s_.prior = prior; }

    /// After match(): matched points of view v, and the sum of their squared distances (m²).
    std::size_t matched(std::size_t v) const { return matched_[v]; }
    double sq_sum(std::size_t v) const { return sq_sum_[v]; }
    /// After match(): share of the sampled working points (every `stride`-th of each view)
    /// that matched.
    double overlap() const;
    /// After match(): RMS distance of all views' matched points (m); 0 when none matched.
    double rms() const;

private:
    struct Match {
        std::int32_t view = -1;  // partner view of the match, -1 = none
        std::uint32_t index = 0;
        double sq_dist = 0.0;
    };
    std::vector<Working>& work_;
    std::vector<std::vector<std::size_t>> partners_;
    JointSettings s_;
    std::vector<std::size_t> offset_;  // first point of each view in the flattened arrays
    std::vector<Match> match_;
    std::vector<std::uint64_t> hint_;  // last match (view << 32 | index) per point
    std::vector<std::size_t> matched_;
    std::size_t sampled_ = 0;  // working points the last match() sampled
    std::vector<double> sq_sum_;
};

/// Partner views for the joint refinement: the views within `hops` pairs of the selected pairs
/// (the pairs' graph), or every other view when there are no pairs.
std::vector<std::vector<std::size_t>> partner_views(std::size_t nv,
                                                    const std::vector<PairAlignment>& pairs,
                                                    int hops);

}  // namespace rgbd::registration::detail
