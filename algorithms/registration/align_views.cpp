// Joint multi-view point-to-plane refinement (see icp.hpp for the contract): the working
// copies, then the pairwise stage and pose graph (pairwise_stage.cpp), then the joint rounds
// (joint_refinement.cpp), then the per-view evaluation and verdicts.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <tuple>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/pair_icp.hpp"
#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/registration/align_stages.hpp"
#include "algorithms/registration/icp.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "algorithms/sampling/voxel_downsample.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::registration {

using detail::kDegToRad;
using detail::motion_at;
using detail::view_name;
using detail::Working;

namespace {

constexpr std::size_t kMinMatches = 12;  // fewer: the view keeps its pose this iteration
/// Strided joint rounds keep at least about this many working points of the smallest view.
constexpr std::size_t kMinSampled = 1000;
/// The safety net's joint rounds from the initial poses, and the overlap both starts are judged
/// by, use every 8th working point at most finely: the overlap is a share, well estimated from
/// such a sample (50 views of a person: 50,000 points), and a winning safety net gets the finest
/// rounds on every point afterwards.
constexpr std::size_t kSafetyStride = 8;
/// The safety net's start wins when its matched share beats the pairwise start's by more.
constexpr double kSafetyGain = 0.05;
/// Joint matches look for partners within this many pairs of the pair graph (a ring of 8 at 45
/// degrees: the views at 45 and 90 degrees; a 50-frame turn: two frames either side).
constexpr int kPartnerHops = 2;

}  // namespace

MultiViewResult align_views(const std::vector<PointCloud>& views, const MultiViewOptions& options,
                            const Progress& progress) {
    options.check();
    Stopwatch watch;
    const std::size_t nv = views.size();
    RGBD_CHECK(nv >= 2, "align_views: needs at least 2 views, got " + std::to_string(nv));
    RGBD_CHECK(
        options.fixed_view < nv,
        "align_views: fixed_view " + std::to_string(options.fixed_view) + " is out of range");
    for (const PointCloud& v : views) {
        RGBD_CHECK(v.size() >= 3, "align_views: " + view_name(v) + " has fewer than 3 points");
        RGBD_CHECK(v.view.frame == ViewFrame::kWorld || v.view.world_from_sensor.has_value(),
                   "align_views: " + view_name(v) +
                       " is in its sensor frame but has no world_from_sensor pose");
    }

    // Poses are estimated on measured points only (docs/method.md order note): copies of
    // the views that carry super-resolved points (prop::kSynthetic = 1) without them.
    std::vector<PointCloud> measured_copies;
    measured_copies.reserve(nv);
    std::vector<const PointCloud*> measured(nv);
    for (std::size_t v = 0; v < nv; ++v) {
        measured[v] = &views[v];
        const auto synthetic = views[v].flag(prop::kSynthetic);
        if (!synthetic) continue;
        // The measured points (a seventh of an up-sampled view) inserted one by one into an
        // empty set with the same properties, in the order that partitioning a copy of the
        // whole view left them (the order the copy had when it was made that way): collecting
        // the garbage of such a copy sorted all its points and was most of this stage's serial
        // time.
        const PointCloud& view = views[v];
        const auto flag = *synthetic;
        std::vector<PointSet::Index> kept(view.points.begin(), view.points.end());
        kept.erase(std::partition(kept.begin(), kept.end(),
                                  [&](PointSet::Index i) { return flag[i] == 0; }),
                   kept.end());
        PointCloud& copy = measured_copies.emplace_back();
        copy.view = view.view;
        copy.points.copy_properties(view.points);
        if (copy.points.properties() == view.points.properties()) {
            copy.points.reserve(kept.size());
            for (PointSet::Index i : kept) copy.points.insert(view.points, i);
        } else {  // another layout: transfer() would pair the wrong properties
            copy = view;
            const auto copy_flag = *copy.flag(prop::kSynthetic);
            copy.points.remove(std::partition(copy.points.begin(), copy.points.end(),
                                              [&](PointSet::Index i) { return copy_flag[i] == 0; }),
                               copy.points.end());
            copy.points.collect_garbage();
        }
        RGBD_CHECK(copy.size() >= 3,
                   "align_views: " + view_name(views[v]) + " has fewer than 3 measured points");
        measured[v] = &copy;
    }

    // Scale: ŝ = median of the views' robust spacings (2000-point samples keep this cheap).
    MultiViewResult result;
    double spacing = options.icp.spacing_m;
    if (spacing <= 0) {
        spacing = sampling::median_view_spacing(measured, 2000);
    }
    RGBD_CHECK(spacing > 0, "align_views: the views have zero point spacing");
    double voxel = options.voxel_m > 0 ? options.voxel_m : options.voxel_factor * spacing;
    if (options.voxel_m <= 0 && options.max_points_per_view > 0) {
        // On a surface, a voxel of edge e keeps about (ŝ / e)^2 of the points.
        std::vector<std::size_t> sizes;
        for (const PointCloud* v : measured) sizes.push_back(v->size());
        const double ratio = static_cast<double>(upper_median(sizes)) /
                             static_cast<double>(options.max_points_per_view);
        if (ratio > 1.0) {
            voxel = std::max(voxel, spacing * std::sqrt(ratio));
            spacing = std::max(spacing, voxel / options.voxel_factor);
        }
    }
    std::vector<double> stage = options.icp.max_distances_m;
    if (stage.empty())
        for (double f : options.icp.max_distance_factors) stage.push_back(f * spacing);
    for (int r = 0; r < options.rounds; ++r)
        result.max_distances_m.push_back(stage[std::min<std::size_t>(r, stage.size() - 1)]);
    result.spacing_m = spacing;
    result.voxel_m = voxel;

    // Working copies, in parallel over the views: down-sampled, normals towards the sensor,
    // intensities and gradients, and one kd-tree per view.
    std::vector<Working> work(nv);
    normals::NormalOptions nopt;
    nopt.k = options.normal_k;
    std::vector<char> colour_of(nv, 0);
    tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t v) {
        PointCloud down = sampling::voxel_downsample(*measured[v], voxel);
        RGBD_CHECK(down.size() >= 3, "align_views: " + view_name(views[v]) +
                                         " has fewer than 3 points after down-sampling");
        std::vector<std::uint32_t> neighbours;  // the normals' kNN, for the gradients too
        const Report nrep = normals::estimate_normals(down, nopt, {}, &neighbours);
        Working& w = work[v];
        w.reg.oriented = nrep["orientation"] == "sensor";
        w.initial = views[v].view.frame == ViewFrame::kSensor ? *views[v].view.world_from_sensor
                                                              : Pose::Identity();
        w.pose = w.initial;
        if (views[v].view.frame == ViewFrame::kSensor)
            w.direction = w.initial.linear().col(2);
        else if (views[v].view.world_from_sensor)
            w.direction = views[v].view.world_from_sensor->linear().col(2);
        const bool colour = down.has_colors();
        colour_of[v] = colour ? 1 : 0;
        std::optional<PointCloud::ColorMaps> cm;
        if (colour) cm = down.colors();
        w.reg.xyz.reserve(down.size());
        w.reg.normals.reserve(down.size());
        for (auto idx : down.points) {
            w.reg.xyz.push_back(to_eigen(down.points.point(idx)));
            w.reg.normals.push_back(to_eigen(down.points.normal(idx)));
            w.reg.centroid += w.reg.xyz.back();
            if (colour) {
                const Rgb c = cm->get(idx);
                w.reg.intensity.push_back((c.r + c.g + c.b) / (3.0f * 255.0f));
            }
        }
        w.reg.centroid /= static_cast<double>(w.reg.xyz.size());
        w.tree = std::make_unique<internal::KdTree>(w.reg.xyz);
        internal::compute_intensity_gradients(w.reg, *w.tree, 16, neighbours);
    });
    bool all_oriented = true, all_colour = true;
    for (std::size_t v = 0; v < nv; ++v) {
        all_oriented = all_oriented && work[v].reg.oriented;
        all_colour = all_colour && colour_of[v] != 0;
    }
    result.working_time_s = watch.seconds();
    if (!report_progress(progress, 0.05)) throw AlgorithmError("align_views: cancelled");
    const bool use_colour = all_colour && options.colour_weight > 0;

    internal::PairIcpSettings pset;
    pset.max_iterations = options.icp.criteria.max_iterations;
    pset.kernel = static_cast<int>(options.icp.kernel);
    pset.kernel_scale = options.icp.kernel_scale;
    pset.cos_gate = options.icp.max_normal_angle_deg >= 180
                        ? -2.0
                        : std::cos(options.icp.max_normal_angle_deg * kDegToRad);
    pset.colour_weight = use_colour ? options.colour_weight : 0.0;
    pset.geometric_sigma = spacing;
    pset.colour_sigma = options.colour_sigma;
    // Pairs only seed the pose graph and the joint rounds: a looser stop than the joint one.
    pset.min_motion = 2.5 * options.min_motion_spacing * spacing;
    pset.distances = stage;
    const double eval_distance = 2.0 * spacing;

    // Whether the initial poses say anything (known, and not every view at the same pose).
    bool all_known = true, all_same = true;
    for (const Working& w : work) all_known = all_known && w.direction.has_value();
    if (all_known)
        for (const Working& w : work)
            all_same = all_same && w.direction->dot(*work[0].direction) > 1 - 1e-9;
    const bool poses_known = all_known && !all_same;

    // Pairwise stage and pose graph.
    std::vector<int> view_pairs(nv, 0);
    std::vector<bool> tied(nv, false);
    if (options.pairwise) {
        detail::PairwiseInputs in;
        in.measured = &measured;
        in.voxel = voxel;
        in.normal_k = options.normal_k;
        in.icp = pset;
        in.eval_distance = eval_distance;
        in.spacing = spacing;
        in.poses_known = poses_known;
        detail::pairwise_stage(work, options, in, result, view_pairs, tied, progress);
    }

    // Joint refinement: each view matched against its partner views' own kd-trees.
    detail::JointSettings js;
    js.kernel = static_cast<int>(options.icp.kernel);
    js.kernel_scale = options.icp.kernel_scale;
    js.cos_gate = options.icp.max_normal_angle_deg >= 180
                      ? -2.0
                      : std::cos(options.icp.max_normal_angle_deg * kDegToRad);
    js.oriented = all_oriented;
    js.colour = use_colour;
    // Colour residuals weighted against geometric ones (both divided by their noise scale).
    js.colour_scale =
        options.colour_weight * (spacing * spacing) / (options.colour_sigma * options.colour_sigma);
    js.colour_sigma = options.colour_sigma;
    js.fixed_view = options.fixed_view;
    detail::JointRefinement joint(
        work,
        detail::partner_views(nv, options.pairwise ? result.pairs : std::vector<PairAlignment>{},
                              kPartnerHops),
        js);
    const IcpCriteria& crit = options.icp.criteria;
    std::size_t smallest_view = work[0].reg.xyz.size();
    for (const Working& w : work) smallest_view = std::min(smallest_view, w.reg.xyz.size());
    // A stride that still samples about kMinSampled points of the smallest view.
    const auto sampled_stride = [&](std::size_t stride) {
        while (stride > 1 && smallest_view / stride < kMinSampled) stride /= 2;
        return stride;
    };
    std::vector<int> moved_iterations(nv, 0);
    std::vector<char> converged(nv, 0);

    // Joint rounds from the current poses: all rounds (coarse to fine) from the initial poses,
    // the finest two (at most 10 iterations each) after the pairwise stage and the pose graph;
    // only the latter also end when the fit stops improving (MultiViewOptions::min_fit_gain).
    // Progress runs from `p0` to `p1` over the rounds (never backwards). No round samples more
    // finely than every `min_stride`-th point.
    auto joint_rounds = [&](bool after_pairwise, double p0, double p1, std::size_t min_stride) {
        const int first_round =
            after_pairwise ? std::max(0, options.rounds - std::min(options.rounds, 2)) : 0;
        for (int round = first_round; round < options.rounds; ++round) {
            const double dmax = result.max_distances_m[round];
            bool round_converged = false;
            const int max_it =
                options.pairwise ? std::min(crit.max_iterations, 10) : crit.max_iterations;
            // Coarse rounds on every 2^k-th working point (k = rounds left, at most 3, at least
            // ~1000 points per view); the finest round on all of them.
            const std::size_t stride = sampled_stride(
                std::max(min_stride, std::size_t{1} << std::min(options.rounds - 1 - round, 3)));
            double previous_rms = 0.0, previous_share = 0.0;
            for (int it = 0; it < max_it; ++it) {
                joint.match(dmax, stride);
                // The previous update's gain in fit (matched RMS distance and share).
                const double share = joint.overlap(), rms = joint.rms();
                if (after_pairwise && it > 0 && options.min_fit_gain > 0 &&
                    previous_rms - rms < options.min_fit_gain * previous_rms &&
                    share - previous_share < options.min_fit_gain * previous_share) {
                    round_converged = true;
                    break;
                }
                previous_rms = rms;
                previous_share = share;
                const std::optional<double> max_motion =
                    joint.step(dmax, kMinMatches, moved_iterations);
                if (!max_motion) break;
                ++result.iterations;
                if (*max_motion <= options.min_motion_spacing * spacing) {
                    round_converged = true;
                    break;
                }
            }
            if (round == options.rounds - 1)
                for (std::size_t v = 0; v < nv; ++v) converged[v] = round_converged ? 1 : 0;
            const double done = double(round + 1 - first_round) / (options.rounds - first_round);
            if (!report_progress(progress, p0 + (p1 - p0) * done))
                throw AlgorithmError("align_views: cancelled");
        }
    };
    // Share of the working points (every stride-th, at least ~1000 per view) matched to another
    // view at the finest distance.
    auto overlap_score = [&](std::size_t stride) {
        joint.match(result.max_distances_m.back(), sampled_stride(stride));
        return joint.overlap();
    };

    // A view's change from its initial pose: rotation (degrees) and the translation of its
    // points' centroid (m); moved_far: past the verdicts' bounds.
    const auto pose_change = [&](std::size_t v) {
        const Pose d = orthonormalized(work[v].pose * work[v].initial.inverse());
        const Eigen::Vector3d c0 = work[v].initial * work[v].reg.centroid;
        return std::make_pair(rotation_error_deg(d, Pose::Identity()), (d * c0 - c0).norm());
    };
    const auto moved_far = [&](const std::pair<double, double>& change) {
        return change.first > options.max_rotation_deg || change.second > options.max_translation_m;
    };
    // The joint rounds' outcome (poses and counters), kept while another start is tried.
    struct JointState {
        std::vector<Pose> poses;
        std::vector<int> moved;
        std::vector<char> converged;
        int iterations = 0;
    };
    const auto save_state = [&] {
        JointState state{std::vector<Pose>(nv), moved_iterations, converged, result.iterations};
        for (std::size_t v = 0; v < nv; ++v) state.poses[v] = work[v].pose;
        return state;
    };
    const auto restore_state = [&](const JointState& state) {
        for (std::size_t v = 0; v < nv; ++v) work[v].pose = state.poses[v];
        moved_iterations = state.moved;
        converged = state.converged;
        result.iterations = state.iterations;
    };

    Stopwatch joint_watch;
    if (options.pairwise && poses_known) {
        // Safety net: on smooth, nearly symmetric shapes pairs can slide where the joint
        // rounds, pinned from both sides, do not. Run those from the initial poses too and keep
        // them when they match clearly more points (the pairs then show their disagreement).
        // A matched share can not exceed 1: when the pairwise start already matches more than
        // 1 - kSafetyGain, the safety net can not win, and is not run.
        joint_rounds(true, 0.35, 0.6, 1);
        const double pair_score = overlap_score(kSafetyStride);
        result.pairwise_fitness = pair_score;
        result.start = "pairwise stage and pose graph";
        if (pair_score + kSafetyGain < 1.0) {
            Stopwatch safety_watch;
            const JointState pair_result = save_state();
            for (std::size_t v = 0; v < nv; ++v) work[v].pose = work[v].initial;
            std::fill(moved_iterations.begin(), moved_iterations.end(), 0);
            joint_rounds(false, 0.6, 0.8, kSafetyStride);
            const double joint_score = overlap_score(kSafetyStride);
            result.joint_only_fitness = joint_score;
            result.safety_net_time_s = safety_watch.seconds();
            if (joint_score > pair_score + kSafetyGain) {
                joint_rounds(true, 0.8, 0.9, 1);  // the finest rounds on every point
                result.start = "initial poses (joint rounds matched more than the pairwise stage)";
            } else {
                restore_state(pair_result);
            }
        }
    } else {
        joint_rounds(options.pairwise, 0.35, 0.9, 1);
        result.start = options.pairwise ? "pairwise stage and pose graph" : "initial poses";
    }

    // A view past the verdicts' bounds from its calibrated pose: all rounds run again from the
    // initial poses, with every free view held towards its initial pose
    // (MultiViewOptions::calibration_prior_rotation_deg). On the jug (rgbd-synth, seed 2) the
    // pairs and the rounds after them turn one view 36.6 degrees about the jug's axis (the
    // rounds from the initial poses alone turn two by 26 and 30); held, no view is off by more
    // than 0.2 degrees.
    const auto count_far = [&] {
        std::size_t n = 0;
        for (std::size_t v = 0; v < nv; ++v) n += moved_far(pose_change(v)) ? 1 : 0;
        return n;
    };
    const std::size_t views_far =
        poses_known && options.calibration_prior_rotation_deg > 0 ? count_far() : 0;
    if (views_far > 0) {
        Stopwatch held_watch;
        MultiViewResult::HeldRetry& held = result.held;
        held.ran = true;
        held.views_far_free = views_far;
        held.free_fitness = overlap_score(kSafetyStride);
        const JointState free_result = save_state();
        joint.set_prior(detail::calibration_prior(spacing, options.calibration_prior_rotation_deg,
                                                  options.calibration_prior_translation_m));
        for (std::size_t v = 0; v < nv; ++v) work[v].pose = work[v].initial;
        std::fill(moved_iterations.begin(), moved_iterations.end(), 0);
        joint_rounds(false, 0.9, 0.95, 1);
        joint.set_prior(Eigen::Matrix<double, 6, 1>::Zero());
        held.views_far_held = count_far();
        held.held_fitness = overlap_score(kSafetyStride);
        held.kept = held.views_far_held < held.views_far_free &&
                    held.held_fitness + kSafetyGain >= held.free_fitness;
        if (held.kept) {
            result.start = "initial poses, held by the calibration prior (joint rounds left " +
                           std::to_string(held.views_far_free) + " view(s) past the bounds)";
        } else {
            restore_state(free_result);
        }
        result.safety_net_time_s += held_watch.seconds();
    }

    // Final per-view evaluation at the finest distance.
    joint.match(result.max_distances_m.back());
    result.joint_time_s = joint_watch.seconds() - result.safety_net_time_s;
    std::vector<std::size_t> matched(nv);
    std::vector<double> sq_sum(nv, 0.0);
    for (std::size_t v = 0; v < nv; ++v) {
        matched[v] = joint.matched(v);
        sq_sum[v] = joint.sq_sum(v);
    }

    // Agreement of every pair with the final poses; loop closure of a ring of pairs.
    std::vector<double> ring_rot(nv, 0.0), ring_trans(nv, 0.0);
    for (PairAlignment& pa : result.pairs) {
        const Pose final_rel = work[pa.target].pose.inverse() * work[pa.source].pose;
        const auto [rot, trans] =
            motion_at(pa.target_from_source.inverse() * final_rel, work[pa.source].reg.centroid);
        pa.ring_rotation_deg = rot;
        pa.ring_translation_m = trans;
        if (!pa.in_graph) continue;
        for (std::size_t v : {pa.target, pa.source}) {
            ring_rot[v] = std::max(ring_rot[v], rot);
            ring_trans[v] = std::max(ring_trans[v], trans);
        }
    }
    const std::vector<std::size_t> order = detail::ring_order(nv, result.pairs);
    if (!order.empty()) {
        LoopClosure& loop = result.loop;
        loop.found = true;
        loop.order = order;
        // Before: the pairwise measurements composed around the cycle (the drift that chaining
        // them would leave). After: the gap that remains at the closing pair (last -> first),
        // its measurement against the final poses.
        Pose before = Pose::Identity();
        for (std::size_t k = 0; k < nv; ++k) {
            const std::size_t a = order[k], b = order[(k + 1) % nv];
            const PairAlignment& p = result.pairs[detail::pair_index(result.pairs, a, b)];
            before = before * detail::relative(p.target_from_source, p.target, a);
        }
        const std::size_t last = order[nv - 1], first = order[0];
        const PairAlignment& closing = result.pairs[detail::pair_index(result.pairs, last, first)];
        const Pose after =
            detail::relative(closing.target_from_source, closing.target, last).inverse() *
            (work[last].pose.inverse() * work[first].pose);
        const Eigen::Vector3d c = work[first].reg.centroid;
        std::tie(loop.before_rotation_deg, loop.before_translation_m) = motion_at(before, c);
        std::tie(loop.after_rotation_deg, loop.after_translation_m) = motion_at(after, c);
    }

    result.verdict = Verdict::kPass;
    for (std::size_t v = 0; v < nv; ++v) {
        const Working& w = work[v];
        ViewAlignment va;
        va.view_id = views[v].view.id;
        va.correction = orthonormalized(w.pose * w.initial.inverse());
        if (views[v].view.frame == ViewFrame::kSensor)
            va.world_from_sensor = w.pose;
        else if (views[v].view.world_from_sensor)
            va.world_from_sensor =
                orthonormalized(va.correction * *views[v].view.world_from_sensor);
        else
            va.world_from_sensor = va.correction;
        const std::size_t n = w.reg.xyz.size();
        va.fitness = static_cast<double>(matched[v]) / static_cast<double>(n);
        va.inlier_rmse = matched[v] ? std::sqrt(sq_sum[v] / matched[v]) : 0.0;
        va.iterations = moved_iterations[v];
        va.converged = converged[v] != 0;
        // Translation of the view's own points (its centroid), not of the world origin.
        std::tie(va.rotation_change_deg, va.translation_change_m) = pose_change(v);
        va.pairs = view_pairs[v];
        va.ring_rotation_deg = ring_rot[v];
        va.ring_translation_m = ring_trans[v];
        const bool far = moved_far({va.rotation_change_deg, va.translation_change_m});
        const bool ring_disagrees =
            va.ring_rotation_deg > options.prune_rotation_deg ||
            va.ring_translation_m > options.prune_translation_spacing * spacing;
        va.verdict = Verdict::kPass;
        if (va.fitness < options.fail_fitness) {
            va.verdict = Verdict::kFail;
            va.reason = "overlaps no other view";
        } else if (options.pairwise && !tied[v]) {
            va.verdict = Verdict::kFail;
            va.reason = "no pair ties it to the others";
        } else if (!options.pairwise && far) {
            va.verdict = Verdict::kFail;
            va.reason = "moved too far from its initial pose";
        } else if (ring_disagrees) {
            va.verdict = Verdict::kWarn;
            va.reason = "its pairs disagree with the final poses";
        } else if (va.fitness < options.warn_fitness) {
            va.verdict = Verdict::kWarn;
            va.reason = "small overlap";
        } else if (far && poses_known) {
            va.verdict = Verdict::kWarn;
            va.reason = "far from its initial pose (calibration off?)";
        }
        if (static_cast<int>(va.verdict) > static_cast<int>(result.verdict))
            result.verdict = va.verdict;
        result.views.push_back(va);
    }
    result.time_s = watch.seconds();
    report_progress(progress, 1.0);
    return result;
}

}  // namespace rgbd::registration
