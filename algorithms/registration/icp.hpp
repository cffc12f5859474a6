// Point-to-plane ICP: pairwise (align_pair) and joint multi-view refinement (align_views)
// (docs/algorithms.md §6-§6.3, §7 fitness / inlier RMSE).
// Sources: Chen and Medioni 1991 (point-to-plane, linearised 6x6 normal equations); Besl and
// McKay 1992; Rusinkiewicz and Levoy 2001 (rejection, coarse-to-fine); robust IRLS kernels and
// convergence criteria as in Open3D pipelines/registration (Registration.h, RobustKernel.h);
// simultaneous multi-view registration as in Pulli 1999 / Neugebauer 1997 (all poses solved in one
// linear system per iteration, one view held fixed as the gauge).
// See also: algorithms/sampling/voxel_downsample.hpp, algorithms/normals/estimate_normals.hpp,
// algorithms/sampling/merge_views.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "toolkit/point_cloud.hpp"
#include "toolkit/pose.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::registration {

/// IRLS weight applied to the point-to-plane residual r (scale k, see IcpOptions).
enum class RobustKernel {
    kNone,   ///< w = 1
    kHuber,  ///< w = k / max(|r|, k)
    kTukey,  ///< w = (1 - min(1, |r| / k)^2)^2
};

/// When one coarse-to-fine stage stops (Open3D ICPConvergenceCriteria plus an update test).
struct IcpCriteria {
    int max_iterations = 30;                ///< iterations per stage (>= 1)
    double relative_fitness = 1e-6;         ///< stop when |Δfitness| / fitness below this ...
    double relative_rmse = 1e-6;            ///< ... and |Δinlier_rmse| / inlier_rmse below this
    double min_rotation_deg = 1e-4;         ///< or when the update rotates less than this ...
    double min_translation_spacing = 1e-4;  ///< ... and translates less than this × ŝ
    void check() const;
};

struct IcpOptions {
    /// Coarse-to-fine maximum correspondence distances in metres. Empty (default): the
    /// `max_distance_factors` times ŝ (ŝ ~ 4 mm for Kinect v2 at 1.5 m gives 48/24/12/6 mm).
    std::vector<double> max_distances_m;
    /// Stage distances as multiples of ŝ, used when `max_distances_m` is empty.
    std::vector<double> max_distance_factors = {12.0, 6.0, 3.0, 1.5};
    /// ŝ in metres; 0 (default) = robust spacing of the source (align_pair) or the median of
    /// the views' spacings (align_views).
    double spacing_m = 0.0;
    RobustKernel kernel = RobustKernel::kTukey;
    /// Kernel scale k as a fraction of the stage's max distance (docs/algorithms.md §6: d_max / 2).
    double kernel_scale = 0.5;
    /// Pairs whose normals differ by more than this are rejected (needs source normals;
    /// >= 180 disables the gate).
    double max_normal_angle_deg = 60.0;
    IcpCriteria criteria;
    void check() const;
};

/// Result of a pairwise alignment. Non-convergence is a result, not an exception.
struct AlignResult {
    Pose target_from_source = Pose::Identity();
    double fitness = 0.0;             ///< matched source points / source points, final max distance
    double inlier_rmse = 0.0;         ///< m, RMS point-to-point distance over matched pairs
    double plane_rmse = 0.0;          ///< m, RMS point-to-plane distance over matched pairs
    std::size_t correspondences = 0;  ///< matched pairs at the final pose
    int iterations = 0;               ///< total over all stages
    bool converged = false;           ///< the last stage met the criteria before max_iterations
    Report to_json() const;
};

/// Pairwise point-to-plane ICP (Chen-Medioni, linearised, robust IRLS weights).
/// @param source  points to move (normals optional: used for the normal-angle gate).
/// @param target  fixed points; must have normals (InputError otherwise, estimate them first).
/// @param initial_target_from_source  starting pose.
/// Correspondence: nearest target point (kd-tree), rejected beyond the stage distance or over
/// the normal angle. Coordinates are used as given (no down-sampling here: voxel_downsample
/// first for speed). Bit-identical results for any TBB thread count (fixed chunks, ordered
/// combine). Throws InputError on empty inputs, non-finite values or a missing target normal map.
AlignResult align_pair(const PointCloud& source, const PointCloud& target,
                       const Pose& initial_target_from_source, const IcpOptions& options);

/// PASS / WARN / FAIL of one view or of a whole alignment.
enum class Verdict { kPass, kWarn, kFail };
const char* to_string(Verdict verdict);

struct MultiViewOptions {
    /// Voxel edge for the working copies, metres; 0 (default) = `voxel_factor` × ŝ.
    double voxel_m = 0.0;
    double voxel_factor = 1.25;  ///< voxel as a multiple of ŝ when voxel_m is 0
    /// When voxel_m is 0, the voxel grows so that a view of median size keeps about this many
    /// working points (0 = no bound): dense views (a 640x480 sequence of 50 frames) then cost
    /// what a Kinect v2 ring costs, and the stage distances grow with the voxel.
    std::size_t max_points_per_view = 8000;
    /// Neighbours for the normals of the working copies (oriented towards each sensor).
    int normal_k = 24;
    /// Index (position in the input vector) of the view held fixed: the gauge.
    std::size_t fixed_view = 0;
    /// Coarse-to-fine rounds; round r uses stage distance r of `icp` (the last one repeated
    /// when there are more rounds than distances). Each round runs up to
    /// icp.criteria.max_iterations joint iterations. After the pairwise stage (below) the views
    /// are close: only the last two rounds (the finest distances) run, with at most 10
    /// iterations each (on 50-view sequences re-matching jitter otherwise uses them all).
    int rounds = 4;
    /// Distances, kernel, normal gate and max_iterations (ŝ: median of the views' spacings).
    IcpOptions icp;
    /// A round has converged when no view's update moves any of its points by more than this
    /// multiple of ŝ. (Re-matching makes joint updates jitter at a few µm, so the pairwise
    /// rotation / translation thresholds of icp.criteria are not used here.)
    double min_motion_spacing = 0.02;
    /// A round of the finest two that refine a start (the pairwise stage and pose graph, or a
    /// winning safety net) also ends when an iteration's re-matching shows that the previous
    /// update improved the fit by less than this fraction (rounds from the initial poses do not
    /// use this test: there the views travel in many steps of small gain each): the matched points'
    /// RMS distance fell by less than min_fit_gain of itself and their share of the working points
    /// rose by less than min_fit_gain of itself (Open3D's relative_rmse / relative_fitness test, at
    /// a level for costly joint iterations). The views then creep along a flat valley of the
    /// objective (on a 50-frame turntable person: 1.4 mm -> 0.09 mm per iteration over 20
    /// iterations, the RMS distance 1.663 -> 1.650 mm), which moves no pose towards the truth. 0 =
    /// off.
    double min_fit_gain = 0.005;
    /// Verdict thresholds: FAIL below fail_fitness or when a pose moved more than
    /// max_rotation_deg / max_translation_m from its initial value; WARN below warn_fitness.
    double fail_fitness = 0.1;
    double warn_fitness = 0.3;
    /// (For views that no PASS / WARN pair supports; a view tied to the ring by pairs may move
    /// as far as the pairs say, and gets WARN for a move beyond these.)
    double max_rotation_deg = 20.0;
    double max_translation_m = 0.2;
    /// Calibration prior (known poses only): when the joint rounds leave a view farther than
    /// max_rotation_deg / max_translation_m from its initial pose, all rounds run again from the
    /// initial poses with every free view held towards its initial pose, as by a rig calibrated to
    /// about this rotation and translation (a diagonal prior whose information is ŝ² / σ², in
    /// the units of the point-to-plane terms). Where the shape constrains a view the points
    /// outweigh it (a view of a few thousand matched points at 0.1 m: ~10³ times); along a
    /// direction the shape leaves free (a surface of revolution turning about its axis) the
    /// prior decides. The held result is kept when fewer views end past the bounds and its
    /// matched share is at most 0.05 below the free one's. 0 = no retry.
    double calibration_prior_rotation_deg = 1.0;
    double calibration_prior_translation_m = 0.01;

    /// Pairwise stage (docs/algorithms.md §6), before the joint rounds: every overlapping pair is
    /// registered by point-to-plane ICP with a colour term from the initial relative pose and,
    /// with `global_registration`, also from an FPFH + RANSAC hypothesis (the better one by
    /// fitness wins); then a pose graph over the pairs that pass spreads the loop error and
    /// gives the joint rounds their start. Pairs: when the views' sensor directions are known,
    /// each view with its `pair_neighbours` nearest views by viewing direction within
    /// `max_pair_angle_deg`; otherwise (or when all directions are the same: poses unknown)
    /// consecutive views in stream order plus the last-first pair (a closed ring or
    /// turntable sequence).
    bool pairwise = true;
    bool global_registration = true;
    int pair_neighbours = 2;
    double max_pair_angle_deg = 75.0;
    /// Voxel of the feature copies as a multiple of the working voxel; FPFH radius as a
    /// multiple of the feature voxel.
    double feature_voxel_factor = 2.5;
    double feature_radius_factor = 5.0;
    int ransac_iterations = 20000;
    /// When sensor poses are known, pair results (from either start) that turn more than this
    /// from the initial relative pose, or move the source's centroid more than
    /// max_prior_translation_m from where the initial pose puts it, are discarded (a rig
    /// calibration is roughly right; >= 180 degrees disables both bounds): the initial start
    /// is then retried with the finest two distances only, else kept unrefined. A global
    /// hypothesis replaces the initial one only when its share of matched points whose colour
    /// also agrees (plain fitness without colour) is higher by at least global_min_gain (on a
    /// shape that slides, geometry prefers the most overlap; colour the right place).
    double max_prior_rotation_deg = 20.0;
    double max_prior_translation_m = 0.5;
    double global_min_gain = 0.02;
    /// The global hypothesis is tried on every pair (true), or (false) only on pairs whose
    /// start from the initial poses did not settle it: poses unknown (or all alike, as with
    /// --ignore-poses) or bounds off, or the initial start's result left the bounds or would
    /// not PASS (pair_warn_fitness). With known poses a passing pair then costs no features
    /// and no RANSAC.
    bool global_always = false;
    /// Weight of the colour term (Park et al. 2017, intensity residuals scaled by
    /// colour_sigma, geometric ones by ŝ) in the pairwise and joint stages; 0 = geometry only.
    double colour_weight = 0.1;
    double colour_sigma = 0.05;
    /// Pair verdicts: FAIL below pair_fail_fitness (share of the smaller view matched within
    /// 2ŝ), or when the pose graph prunes the pair as inconsistent with the ring; WARN below
    /// pair_warn_fitness.
    double pair_fail_fitness = 0.08;
    double pair_warn_fitness = 0.2;
    double prune_rotation_deg = 2.0;
    double prune_translation_spacing = 5.0;  ///< pose-graph pruning translation, × ŝ
    std::uint64_t seed = 0;
    void check() const;
};

/// Outcome of one pair of the pairwise stage.
struct PairAlignment {
    std::size_t target = 0, source = 0;  ///< positions in the input
    Pose target_from_source = Pose::Identity();
    std::string method;              ///< "initial" or "global": which start won
    double fitness = 0.0;            ///< matched share of the source working points (within 2ŝ)
    double inlier_rmse = 0.0;        ///< m
    double colour_rmse = 0.0;        ///< intensity residual (Park's model) over matched pairs
    std::size_t ransac_inliers = 0;  ///< of the global hypothesis; 0 when not tried
    /// Whether the global hypothesis was tried (see MultiViewOptions::global_always).
    bool global_tried = false;
    int candidates = 1;  ///< distinct poses considered (initial, global)
    /// Disagreement with the final poses: rotation and translation of
    /// measured^-1 * (final relative pose), translation at the source's centroid.
    double ring_rotation_deg = 0.0;
    double ring_translation_m = 0.0;
    bool in_graph = false;  ///< used by the pose graph (not pruned)
    Verdict verdict = Verdict::kFail;
    std::string reason;  ///< why not PASS
};

/// Loop closure of a ring of pairs (when the pairs form one cycle).
struct LoopClosure {
    bool found = false;
    std::vector<std::size_t> order;    ///< positions around the cycle
    double before_rotation_deg = 0.0;  ///< composed pairwise measurements around the cycle
    double before_translation_m = 0.0;
    /// The gap left at the closing pair (last -> first): its measurement against the final
    /// poses, i.e. the loop error after the pose graph and the joint rounds spread it.
    double after_rotation_deg = 0.0;
    double after_translation_m = 0.0;
};

/// Outcome for one view of align_views.
struct ViewAlignment {
    int view_id = -1;  ///< view.id of the input
    /// Refined world_from_sensor. For a world-frame view without a pose, equal to `correction`.
    Pose world_from_sensor = Pose::Identity();
    /// Rigid motion from the initial world placement to the refined one
    /// (world_from_world_initial); apply it to a world-frame copy of the view.
    Pose correction = Pose::Identity();
    double fitness = 0.0;      ///< share of the view's working points matched to other views
    double inlier_rmse = 0.0;  ///< m, over those matches
    int iterations = 0;        ///< joint iterations in which this view moved
    bool converged = false;
    double rotation_change_deg = 0.0;   ///< |correction| rotation
    double translation_change_m = 0.0;  ///< |correction| translation at the view's centroid
    /// Worst disagreement of the view's graph pairs with the final poses.
    double ring_rotation_deg = 0.0;
    double ring_translation_m = 0.0;
    int pairs = 0;  ///< PASS / WARN pairs that tie the view to the ring
    Verdict verdict = Verdict::kFail;
    std::string reason;  ///< why not PASS
};

struct MultiViewResult {
    std::vector<ViewAlignment> views;  ///< same order as the input
    std::vector<PairAlignment> pairs;  ///< the pairwise stage (empty when off)
    /// Where the joint rounds that won started. With known initial poses the joint rounds also
    /// run from them (all rounds) and win when their mean matched share beats the pairwise
    /// start's by more than 0.05 (smooth, nearly symmetric shapes where pairs slide); they are
    /// not run when the pairwise start matches more than 0.95, since a share can not exceed 1.
    std::string start;
    double pairwise_fitness = 0.0;    ///< mean matched share from the pairwise start
    double joint_only_fitness = 0.0;  ///< ... from the initial poses (0 when not run)
    /// The calibration prior's retry (MultiViewOptions::calibration_prior_rotation_deg): whether
    /// it ran, the views past the bounds before and after it, the matched shares of the free
    /// and held results, and whether the held one was kept.
    struct HeldRetry {
        bool ran = false, kept = false;
        std::size_t views_far_free = 0, views_far_held = 0;
        double free_fitness = 0.0, held_fitness = 0.0;
    } held;
    LoopClosure loop;
    double working_time_s = 0.0;          ///< working copies: down-sampling, normals, kd-trees
    double pairwise_time_s = 0.0;         ///< pairwise stage and pose graph
    double safety_net_time_s = 0.0;       ///< joint rounds from the initial poses, free and held
                                          ///< (0 when not run)
    double joint_time_s = 0.0;            ///< joint rounds that refine the winning start
    Verdict verdict = Verdict::kFail;     ///< the worst of the views' verdicts
    double spacing_m = 0.0;               ///< ŝ used
    double voxel_m = 0.0;                 ///< voxel used for the working copies
    std::vector<double> max_distances_m;  ///< distance of each round
    int iterations = 0;                   ///< joint iterations over all rounds
    double time_s = 0.0;
    Report to_json() const;
};

/// Joint multi-view point-to-plane refinement of N >= 2 views (a ring of sensors, a turntable
/// sequence). Each view is either
/// - in its sensor frame (view.frame == kSensor): its view.world_from_sensor (required) is the
///   initial pose; or
/// - already in the world frame: its current coordinates are the initial placement, and
///   view.world_from_sensor (optional) tells where its sensor is (used to orient normals and
///   to report the refined pose).
/// Working copies are voxel-downsampled and get normals oriented to their sensor (MST when no
/// sensor is known; the normal gate then ignores the sign). Every iteration matches each working
/// point to the nearest point of any *other* view (one kd-tree over the union at the current
/// poses, rebuilt per iteration), and solves one linear system for all poses but the fixed one,
/// so errors are spread over the ring in one step instead of diffusing view by view.
/// Views with fewer than 12 matches in an iteration keep their pose for that iteration.
/// Verdicts as in MultiViewOptions. Deterministic for any thread count.
/// Throws InputError for fewer than 2 views, an empty view, a sensor-frame view without pose,
/// or fixed_view out of range; AlgorithmError("cancelled") when `progress` returns false.
MultiViewResult align_views(const std::vector<PointCloud>& views, const MultiViewOptions& options,
                            const Progress& progress = {});

/// Applies an align_views result: every view ends in the world frame at its refined placement,
/// with view.world_from_sensor updated (set when it was known). Sizes must match (InputError).
void apply_alignment(std::vector<PointCloud>& views, const MultiViewResult& result);

}  // namespace rgbd::registration
