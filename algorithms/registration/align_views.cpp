// Joint multi-view point-to-plane refinement (see icp.hpp for the contract).
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>

#include "algorithms/internal/icp_math.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/pair_icp.hpp"
#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/registration/global_registration.hpp"
#include "algorithms/registration/icp.hpp"
#include "algorithms/registration/pose_graph.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "algorithms/sampling/voxel_downsample.hpp"
#include "toolkit/error.hpp"

namespace rgbd::registration {

namespace {

constexpr std::size_t kChunk = 512;
constexpr std::size_t kCandidates = 12;  // kNN over the union; first one of another view wins
constexpr std::size_t kMinMatches = 12;  // fewer: the view keeps its pose this iteration
constexpr double kDegToRad = M_PI / 180.0;

std::string view_name(const PointCloud& cloud) { return "view " + std::to_string(cloud.view.id); }

/// Working copy of one view: points, normals, intensities and intensity gradients in the frame
/// of its initial pose `initial`.
struct Working {
    internal::RegCloud reg;
    std::unique_ptr<internal::KdTree> tree;    // over reg.xyz (pair targets)
    Pose initial = Pose::Identity();           // world_from_working at the start
    Pose pose = Pose::Identity();              // current world_from_working
    std::optional<Eigen::Vector3d> direction;  // viewing direction in the world, when known
};

/// Rotation angle and translation at point c (working frame of the source) of the motion d.
std::pair<double, double> motion_at(const Pose& d, const Eigen::Vector3d& c) {
    return {rotation_error_deg(d, Pose::Identity()), (d * c - c).norm()};
}

/// Pairs of the pairwise stage (see MultiViewOptions::pairwise). `by_direction`: the views'
/// viewing directions are known and tell something (not all the same); else stream order.
std::vector<std::pair<std::size_t, std::size_t>> select_pairs(const std::vector<Working>& work,
                                                              const MultiViewOptions& o,
                                                              bool by_direction) {
    const std::size_t nv = work.size();
    std::vector<std::pair<std::size_t, std::size_t>> pairs;
    auto add = [&](std::size_t a, std::size_t b) {
        const auto p = std::minmax(a, b);
        if (std::find(pairs.begin(), pairs.end(), std::make_pair(p.first, p.second)) == pairs.end())
            pairs.emplace_back(p.first, p.second);
    };
    if (!by_direction) {
        for (std::size_t v = 0; v + 1 < nv; ++v) add(v, v + 1);
        if (nv >= 3) add(nv - 1, 0);
    } else {
        const double cos_max = std::cos(o.max_pair_angle_deg * kDegToRad);
        for (std::size_t v = 0; v < nv; ++v) {
            std::vector<std::pair<double, std::size_t>> by_angle;
            for (std::size_t u = 0; u < nv; ++u)
                if (u != v) by_angle.emplace_back(-work[v].direction->dot(*work[u].direction), u);
            std::sort(by_angle.begin(), by_angle.end());
            int taken = 0;
            for (const auto& [negcos, u] : by_angle) {
                if (taken >= o.pair_neighbours) break;
                if (-negcos < cos_max && taken > 0) break;  // the nearest view always pairs
                add(v, u);
                ++taken;
            }
        }
    }
    std::sort(pairs.begin(), pairs.end());
    return pairs;
}

/// Positions around the cycle when `pairs` (indices into `list`, usable ones) form exactly
/// one cycle through all views; empty otherwise.
std::vector<std::size_t> ring_order(std::size_t nv, const std::vector<PairAlignment>& list) {
    std::vector<std::vector<std::size_t>> adj(nv);
    for (const PairAlignment& p : list) {
        if (!p.in_graph) continue;
        adj[p.target].push_back(p.source);
        adj[p.source].push_back(p.target);
    }
    if (nv < 3) return {};
    for (const auto& a : adj)
        if (a.size() != 2) return {};
    std::vector<std::size_t> order{0};
    std::size_t prev = 0, cur = std::min(adj[0][0], adj[0][1]);
    while (cur != 0 && order.size() <= nv) {
        order.push_back(cur);
        const std::size_t next = adj[cur][0] == prev ? adj[cur][1] : adj[cur][0];
        prev = cur;
        cur = next;
    }
    if (order.size() != nv) return {};
    return order;
}

/// Index in `list` of the pair of views a and b (either order); list.size() when none.
std::size_t pair_index(const std::vector<PairAlignment>& list, std::size_t a, std::size_t b) {
    for (std::size_t k = 0; k < list.size(); ++k)
        if ((list[k].target == a && list[k].source == b) ||
            (list[k].target == b && list[k].source == a))
            return k;
    return list.size();
}

/// a_from_b of a pair measurement target_from_source of the pair whose target is `target`.
Pose relative(const Pose& target_from_source, std::size_t target, std::size_t a) {
    return target == a ? target_from_source : Pose(target_from_source.inverse());
}

/// One source point's match, written by the parallel pass, read in point order.
struct Match {
    std::int64_t other = -1;  // index into the union, -1 = none
    double sq_dist = 0.0;
    double residual = 0.0;
};

}  // namespace

const char* to_string(Verdict verdict) {
    switch (verdict) {
        case Verdict::kPass:
            return "PASS";
        case Verdict::kWarn:
            return "WARN";
        case Verdict::kFail:
            return "FAIL";
    }
    return "?";
}

void MultiViewOptions::check() const {
    icp.check();
    RGBD_CHECK(std::isfinite(voxel_m) && voxel_m >= 0, "align_views: voxel_m must be >= 0");
    RGBD_CHECK(std::isfinite(voxel_factor) && voxel_factor > 0 && voxel_factor <= 100,
               "align_views: voxel_factor must be in (0, 100]");
    RGBD_CHECK(normal_k >= 3 && normal_k <= 1024, "align_views: normal_k must be in [3, 1024]");
    RGBD_CHECK(max_points_per_view == 0 || max_points_per_view >= 100,
               "align_views: max_points_per_view must be 0 (no bound) or at least 100");
    RGBD_CHECK(std::isfinite(min_motion_spacing) && min_motion_spacing >= 0,
               "align_views: min_motion_spacing must be >= 0");
    RGBD_CHECK(rounds >= 1 && rounds <= 1000, "align_views: rounds must be in [1, 1000]");
    RGBD_CHECK(fail_fitness >= 0 && fail_fitness <= 1 && warn_fitness >= 0 && warn_fitness <= 1,
               "align_views: fitness thresholds must be in [0, 1]");
    RGBD_CHECK(max_rotation_deg > 0 && max_translation_m > 0,
               "align_views: pose-change limits must be positive");
    RGBD_CHECK(pair_neighbours >= 1 && pair_neighbours <= 64,
               "align_views: pair_neighbours must be in [1, 64]");
    RGBD_CHECK(max_pair_angle_deg > 0 && max_pair_angle_deg <= 180,
               "align_views: max_pair_angle_deg must be in (0, 180]");
    RGBD_CHECK(std::isfinite(feature_voxel_factor) && feature_voxel_factor >= 1 &&
                   feature_voxel_factor <= 100,
               "align_views: feature_voxel_factor must be in [1, 100]");
    RGBD_CHECK(std::isfinite(feature_radius_factor) && feature_radius_factor >= 1 &&
                   feature_radius_factor <= 100,
               "align_views: feature_radius_factor must be in [1, 100]");
    RGBD_CHECK(ransac_iterations >= 1 && ransac_iterations <= 10000000,
               "align_views: ransac_iterations must be in [1, 1e7]");
    RGBD_CHECK(max_prior_rotation_deg > 0, "align_views: max_prior_rotation_deg must be > 0");
    RGBD_CHECK(std::isfinite(max_prior_translation_m) && max_prior_translation_m > 0,
               "align_views: max_prior_translation_m must be > 0");
    RGBD_CHECK(std::isfinite(global_min_gain) && global_min_gain >= 0 && global_min_gain <= 1,
               "align_views: global_min_gain must be in [0, 1]");
    RGBD_CHECK(std::isfinite(colour_weight) && colour_weight >= 0 && colour_weight <= 100,
               "align_views: colour_weight must be in [0, 100]");
    RGBD_CHECK(std::isfinite(colour_sigma) && colour_sigma > 0 && colour_sigma <= 1,
               "align_views: colour_sigma must be in (0, 1]");
    RGBD_CHECK(pair_fail_fitness >= 0 && pair_fail_fitness <= 1 && pair_warn_fitness >= 0 &&
                   pair_warn_fitness <= 1,
               "align_views: pair fitness thresholds must be in [0, 1]");
    RGBD_CHECK(prune_rotation_deg > 0 && prune_translation_spacing > 0,
               "align_views: prune thresholds must be positive");
}

Report MultiViewResult::to_json() const {
    Report r;
    r["verdict"] = to_string(verdict);
    r["spacing_m"] = spacing_m;
    r["voxel_m"] = voxel_m;
    r["max_distances_m"] = max_distances_m;
    r["iterations"] = iterations;
    r["time_s"] = time_s;
    r["views"] = Report::array();
    for (const ViewAlignment& v : views) {
        Report j;
        j["view"] = v.view_id;
        j["verdict"] = to_string(v.verdict);
        j["world_from_sensor"] = pose_to_3x4(v.world_from_sensor);
        j["correction"] = pose_to_3x4(v.correction);
        j["fitness"] = v.fitness;
        j["inlier_rmse_m"] = v.inlier_rmse;
        j["iterations"] = v.iterations;
        j["converged"] = v.converged;
        j["rotation_change_deg"] = v.rotation_change_deg;
        j["translation_change_m"] = v.translation_change_m;
        j["ring_rotation_deg"] = v.ring_rotation_deg;
        j["ring_translation_m"] = v.ring_translation_m;
        j["pairs"] = v.pairs;
        if (!v.reason.empty()) j["reason"] = v.reason;
        r["views"].push_back(j);
    }
    r["pairwise_time_s"] = pairwise_time_s;
    r["start"] = start;
    r["pairwise_fitness"] = pairwise_fitness;
    r["joint_only_fitness"] = joint_only_fitness;
    r["pairs"] = Report::array();
    for (const PairAlignment& p : pairs) {
        Report j;
        j["target"] = p.target;
        j["source"] = p.source;
        j["verdict"] = to_string(p.verdict);
        if (!p.reason.empty()) j["reason"] = p.reason;
        j["method"] = p.method;
        j["target_from_source"] = pose_to_3x4(p.target_from_source);
        j["fitness"] = p.fitness;
        j["inlier_rmse_m"] = p.inlier_rmse;
        j["colour_rmse"] = p.colour_rmse;
        j["ransac_inliers"] = p.ransac_inliers;
        j["candidates"] = p.candidates;
        j["in_graph"] = p.in_graph;
        j["ring_rotation_deg"] = p.ring_rotation_deg;
        j["ring_translation_m"] = p.ring_translation_m;
        r["pairs"].push_back(j);
    }
    if (loop.found) {
        Report l;
        l["order"] = loop.order;
        l["before_rotation_deg"] = loop.before_rotation_deg;
        l["before_translation_m"] = loop.before_translation_m;
        l["after_rotation_deg"] = loop.after_rotation_deg;
        l["after_translation_m"] = loop.after_translation_m;
        r["loop_closure"] = l;
    }
    return r;
}

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

    // Poses are estimated on measured points only (ALGORITHMS.md §0.3 order note): copies of
    // the views that carry super-resolved points (prop::kSynthetic = 1) without them.
    std::vector<PointCloud> measured_copies;
    measured_copies.reserve(nv);
    std::vector<const PointCloud*> measured(nv);
    for (std::size_t v = 0; v < nv; ++v) {
        measured[v] = &views[v];
        const auto synthetic = views[v].flag(prop::kSynthetic);
        if (!synthetic) continue;
        PointCloud& copy = measured_copies.emplace_back(views[v]);
        const auto flag = *copy.flag(prop::kSynthetic);
        copy.points.remove(std::partition(copy.points.begin(), copy.points.end(),
                                          [&](PointSet::Index i) { return flag[i] == 0; }),
                           copy.points.end());
        copy.points.collect_garbage();
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
        std::nth_element(sizes.begin(), sizes.begin() + nv / 2, sizes.end());
        const double ratio =
            static_cast<double>(sizes[nv / 2]) / static_cast<double>(options.max_points_per_view);
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

    // Working copies: down-sampled, normals towards the sensor, intensities and gradients.
    std::vector<Working> work(nv);
    normals::NormalOptions nopt;
    nopt.k = options.normal_k;
    bool all_oriented = true, all_colour = true;
    for (std::size_t v = 0; v < nv; ++v) {
        PointCloud down = sampling::voxel_downsample(*measured[v], voxel);
        RGBD_CHECK(down.size() >= 3, "align_views: " + view_name(views[v]) +
                                         " has fewer than 3 points after down-sampling");
        const Report nrep = normals::estimate_normals(down, nopt);
        Working& w = work[v];
        w.reg.oriented = nrep["orientation"] == "sensor";
        all_oriented = all_oriented && w.reg.oriented;
        w.initial = views[v].view.frame == ViewFrame::kSensor ? *views[v].view.world_from_sensor
                                                              : Pose::Identity();
        w.pose = w.initial;
        if (views[v].view.frame == ViewFrame::kSensor)
            w.direction = w.initial.linear().col(2);
        else if (views[v].view.world_from_sensor)
            w.direction = views[v].view.world_from_sensor->linear().col(2);
        const bool colour = down.has_colors();
        all_colour = all_colour && colour;
        std::optional<PointCloud::ColorMaps> cm;
        if (colour) cm = down.colors();
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
        internal::compute_intensity_gradients(w.reg, *w.tree, 16);
        if (!report_progress(progress, 0.05 * (v + 1) / nv))
            throw AlgorithmError("align_views: cancelled");
    }
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
        Stopwatch pair_watch;
        const auto selected = select_pairs(work, options, poses_known);
        // Feature copies (coarser voxel) for the global hypotheses.
        std::vector<std::vector<Eigen::Vector3d>> fxyz(nv);
        std::vector<std::vector<Fpfh>> feats(nv);
        if (options.global_registration) {
            const double fvoxel = options.feature_voxel_factor * voxel;
            for (std::size_t v = 0; v < nv; ++v) {
                PointCloud fc = sampling::voxel_downsample(*measured[v], fvoxel);
                if (fc.size() < 10) continue;
                normals::estimate_normals(fc, nopt);
                std::vector<Eigen::Vector3d> fn;
                for (auto idx : fc.points) {
                    fxyz[v].push_back(to_eigen(fc.points.point(idx)));
                    fn.push_back(to_eigen(fc.points.normal(idx)).normalized());
                }
                feats[v] = compute_fpfh(fxyz[v], fn, options.feature_radius_factor * fvoxel);
            }
        }
        result.pairs.resize(selected.size());
        // Candidate outcomes per pair: from the initial pose, and from the global hypothesis
        // when it ends elsewhere (and within the prior's bounds). Index 0 = the default choice.
        struct Candidate {
            internal::PairIcpOutcome outcome;
            const char* method;
        };
        std::vector<std::vector<Candidate>> cands(selected.size());
        tbb::parallel_for(std::size_t{0}, selected.size(), [&](std::size_t k) {
            const auto [a, b] = selected[k];  // target a, source b
            PairAlignment& pa = result.pairs[k];
            pa.target = a;
            pa.source = b;
            const Pose prior = work[a].initial.inverse() * work[b].initial;
            const bool bounded =
                work[a].direction && work[b].direction && options.max_prior_rotation_deg < 180;
            const Eigen::Vector3d& c = work[b].reg.centroid;
            // A result that left the calibration's bounds slid into a wrong basin (a head is
            // nearly a surface of revolution).
            auto within = [&](const Pose& z) {
                if (!bounded) return true;
                const auto [prot, ptrans] = motion_at(prior.inverse() * z, c);
                return prot <= options.max_prior_rotation_deg &&
                       ptrans <= options.max_prior_translation_m;
            };
            auto& list = cands[k];
            // From the initial pose: the full coarse-to-fine schedule, and (when the poses are
            // known) the finest two distances alone, which cannot slide far on smooth, nearly
            // symmetric shapes; the one with more colour-consistent matches within the bounds.
            internal::PairIcpSettings fine = pset;
            fine.distances.assign(
                pset.distances.end() - std::min<std::size_t>(2, pset.distances.size()),
                pset.distances.end());
            internal::PairIcpOutcome first = internal::pair_icp(
                work[b].reg, work[a].reg, *work[a].tree, prior, pset, eval_distance);
            bool first_ok = within(first.target_from_source);
            if (bounded) {
                internal::PairIcpOutcome near = internal::pair_icp(
                    work[b].reg, work[a].reg, *work[a].tree, prior, fine, eval_distance);
                if (within(near.target_from_source) &&
                    (!first_ok || near.consistent > first.consistent)) {
                    first = std::move(near);
                    first_ok = true;
                }
            }
            if (!first_ok) {  // keep the calibration, unrefined
                fine.max_iterations = 0;
                first = internal::pair_icp(work[b].reg, work[a].reg, *work[a].tree, prior, fine,
                                           eval_distance);
            }
            list.push_back({std::move(first), "initial"});
            if (!options.global_registration || feats[a].empty() || feats[b].empty()) return;
            RansacOptions ro;
            ro.iterations = options.ransac_iterations;
            ro.inlier_distance = 1.5 * options.feature_voxel_factor * voxel;
            ro.seed = options.seed * 1000003u + a * 1009u + b;
            if (bounded) {
                ro.prior = prior;
                ro.max_prior_rotation_deg = options.max_prior_rotation_deg;
            }
            const RansacResult rr = ransac_feature_match(fxyz[b], feats[b], fxyz[a], feats[a], ro);
            pa.ransac_inliers = rr.inliers;
            if (!rr.found) return;
            // A hypothesis that the initial start already reached needs no second ICP.
            auto differs = [&](const Pose& x, const Pose& y) {
                const auto [r, t] = motion_at(x.inverse() * y, c);
                return r > 2.0 || t > ro.inlier_distance;
            };
            if (!differs(list[0].outcome.target_from_source, rr.target_from_source)) return;
            internal::PairIcpOutcome g =
                internal::pair_icp(work[b].reg, work[a].reg, *work[a].tree, rr.target_from_source,
                                   pset, eval_distance);
            if (!within(g.target_from_source)) return;  // slid out of the bounds
            if (!differs(list[0].outcome.target_from_source, g.target_from_source)) return;
            const double n = static_cast<double>(work[b].reg.xyz.size());
            const bool better = double(g.consistent) / n >=
                                double(list[0].outcome.consistent) / n + options.global_min_gain;
            list.push_back({std::move(g), "global"});
            if (better) std::swap(list[0], list[1]);
        });
        if (!report_progress(progress, 0.3)) throw AlgorithmError("align_views: cancelled");

        std::vector<std::size_t> choice(selected.size(), 0);
        auto fill = [&](std::size_t k) {
            PairAlignment& pa = result.pairs[k];
            const internal::PairIcpOutcome& best = cands[k][choice[k]].outcome;
            pa.method = cands[k][choice[k]].method;
            pa.candidates = static_cast<int>(cands[k].size());
            pa.target_from_source = best.target_from_source;
            // Fitness as the share of the smaller view: overlap, not view size.
            pa.fitness =
                std::min(1.0, static_cast<double>(best.matched) /
                                  static_cast<double>(std::min(work[pa.target].reg.xyz.size(),
                                                               work[pa.source].reg.xyz.size())));
            pa.inlier_rmse = best.rmse;
            pa.colour_rmse = best.colour_rmse;
            pa.reason.clear();
            if (best.matched < 30 || pa.fitness < options.pair_fail_fitness) {
                pa.verdict = Verdict::kFail;
                pa.reason = "too little overlap";
            } else if (pa.fitness < options.pair_warn_fitness) {
                pa.verdict = Verdict::kWarn;
                pa.reason = "small overlap";
            } else {
                pa.verdict = Verdict::kPass;
            }
            pa.in_graph = pa.verdict != Verdict::kFail;
        };
        for (std::size_t k = 0; k < selected.size(); ++k) fill(k);

        // On a ring (the usable pairs form one cycle), the loop decides between candidates:
        // the combination whose composition around the cycle is nearest to the identity
        // (exhaustive for up to 10 ambiguous pairs, else one pass of coordinate descent).
        const std::vector<std::size_t> cycle = ring_order(nv, result.pairs);
        std::vector<std::size_t> ambiguous;
        for (std::size_t k = 0; k < selected.size(); ++k)
            if (cands[k].size() > 1 && result.pairs[k].in_graph) ambiguous.push_back(k);
        if (!cycle.empty() && !ambiguous.empty()) {
            const double trans_scale = options.prune_translation_spacing * spacing;
            std::vector<std::size_t> cycle_pair(nv);
            for (std::size_t i = 0; i < nv; ++i)
                cycle_pair[i] = pair_index(result.pairs, cycle[i], cycle[(i + 1) % nv]);
            auto loop_cost = [&]() {
                Pose loop = Pose::Identity();
                for (std::size_t i = 0; i < nv; ++i) {
                    const std::size_t k = cycle_pair[i];
                    loop = loop * relative(cands[k][choice[k]].outcome.target_from_source,
                                           result.pairs[k].target, cycle[i]);
                }
                const auto [r, t] = motion_at(loop, work[cycle[0]].reg.centroid);
                return r / options.prune_rotation_deg + t / trans_scale;
            };
            std::vector<std::size_t> best_choice = choice;
            double best_cost = loop_cost();
            if (ambiguous.size() <= 10) {
                for (std::size_t mask = 1; mask < (std::size_t{1} << ambiguous.size()); ++mask) {
                    for (std::size_t q = 0; q < ambiguous.size(); ++q)
                        choice[ambiguous[q]] = (mask >> q) & 1u;
                    const double cost = loop_cost();
                    if (cost < best_cost) {
                        best_cost = cost;
                        best_choice = choice;
                    }
                }
            } else {
                for (std::size_t k : ambiguous) {
                    choice = best_choice;
                    choice[k] = 1 - choice[k];
                    const double cost = loop_cost();
                    if (cost < best_cost) {
                        best_cost = cost;
                        best_choice = choice;
                    }
                }
            }
            choice = best_choice;
            for (std::size_t k : ambiguous) fill(k);
        }
        std::vector<Eigen::Matrix<double, 6, 6>> information(selected.size());
        for (std::size_t k = 0; k < selected.size(); ++k)
            information[k] = cands[k][choice[k]].outcome.information;

        // Pose graph over the usable pairs; start from the pairs composed along a spanning tree.
        std::vector<PoseGraphEdge> edges;
        std::vector<std::size_t> edge_pair;
        for (std::size_t k = 0; k < result.pairs.size(); ++k) {
            if (!result.pairs[k].in_graph) continue;
            PoseGraphEdge e;
            e.target = result.pairs[k].target;
            e.source = result.pairs[k].source;
            e.target_from_source = result.pairs[k].target_from_source;
            e.information = information[k];
            edges.push_back(e);
            edge_pair.push_back(k);
        }
        std::vector<Pose> start(nv);
        for (std::size_t v = 0; v < nv; ++v) start[v] = work[v].initial;
        std::vector<bool> placed(nv, false);
        placed[options.fixed_view] = true;
        for (bool grew = true; grew;) {
            grew = false;
            for (const PoseGraphEdge& e : edges) {
                if (placed[e.target] && !placed[e.source]) {
                    start[e.source] = start[e.target] * e.target_from_source;
                    placed[e.source] = grew = true;
                } else if (placed[e.source] && !placed[e.target]) {
                    start[e.target] = start[e.source] * e.target_from_source.inverse();
                    placed[e.target] = grew = true;
                }
            }
        }
        PoseGraphOptions gopt;
        gopt.fixed_node = options.fixed_view;
        gopt.prune_rotation_deg = options.prune_rotation_deg;
        gopt.prune_translation_m = options.prune_translation_spacing * spacing;
        const PoseGraphResult graph = optimise_pose_graph(start, edges, gopt);
        for (std::size_t e = 0; e < edges.size(); ++e) {
            PairAlignment& pa = result.pairs[edge_pair[e]];
            if (graph.active[e]) continue;
            pa.in_graph = false;
            pa.verdict = Verdict::kFail;
            pa.reason = "disagrees with the ring";
        }
        for (std::size_t v = 0; v < nv; ++v)
            if (graph.connected[v]) work[v].pose = graph.poses[v];
        for (const PairAlignment& pa : result.pairs)
            if (pa.in_graph) {
                ++view_pairs[pa.target];
                ++view_pairs[pa.source];
            }
        for (std::size_t v = 0; v < nv; ++v) tied[v] = graph.connected[v] && view_pairs[v] > 0;
        result.pairwise_time_s = pair_watch.seconds();
    }

    // Flattened union: offsets per view, owner per point.
    std::vector<std::size_t> offset(nv + 1, 0);
    for (std::size_t v = 0; v < nv; ++v) offset[v + 1] = offset[v] + work[v].reg.xyz.size();
    const std::size_t total = offset[nv];
    std::vector<std::uint32_t> owner(total);
    for (std::size_t v = 0; v < nv; ++v)
        std::fill(owner.begin() + offset[v], owner.begin() + offset[v + 1], v);
    std::vector<Eigen::Vector3d> world(total), world_n(total), world_d;
    std::vector<float> intensity;
    if (use_colour) {
        world_d.resize(total);
        for (std::size_t v = 0; v < nv; ++v)
            intensity.insert(intensity.end(), work[v].reg.intensity.begin(),
                             work[v].reg.intensity.end());
    }
    std::vector<Match> match(total);
    const std::size_t chunks = (total + kChunk - 1) / kChunk;

    const int kernel = static_cast<int>(options.icp.kernel);
    const double cos_gate = options.icp.max_normal_angle_deg >= 180
                                ? -2.0
                                : std::cos(options.icp.max_normal_angle_deg * kDegToRad);

    // Places every view at its current pose, rebuilds the kd-tree and matches every point to
    // the nearest point of another view. Parallel over fixed chunks; each point writes its own
    // slot, so the outcome does not depend on the thread count.
    auto match_all = [&](double dmax) {
        for (std::size_t v = 0; v < nv; ++v) {
            const Pose& pose = work[v].pose;
            const Eigen::Matrix3d rot = pose.linear();
            for (std::size_t i = 0; i < work[v].reg.xyz.size(); ++i) {
                world[offset[v] + i] = pose * work[v].reg.xyz[i];
                world_n[offset[v] + i] = rot * work[v].reg.normals[i];
                if (use_colour) world_d[offset[v] + i] = rot * work[v].reg.gradient[i];
            }
        }
        const internal::KdTree tree(world);
        const double max_sq = dmax * dmax;
        tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
            std::uint32_t nn[kCandidates];
            double sq[kCandidates];
            const std::size_t end = std::min(total, (c + 1) * kChunk);
            for (std::size_t a = c * kChunk; a < end; ++a) {
                Match& m = match[a];
                m = Match{};
                const std::size_t found = tree.knn(world[a], kCandidates, nn, sq);
                for (std::size_t j = 0; j < found; ++j) {
                    if (sq[j] > max_sq) break;
                    const std::uint32_t b = nn[j];
                    if (owner[b] == owner[a]) continue;
                    const double cosang = world_n[a].dot(world_n[b]);
                    const bool ok =
                        all_oriented ? cosang >= cos_gate : std::abs(cosang) >= cos_gate;
                    if (!ok) break;  // the nearest other-view point decides
                    m.other = b;
                    m.sq_dist = sq[j];
                    m.residual = (world[a] - world[b]).dot(world_n[b]);
                    break;
                }
            }
        });
    };

    // Colour residuals weighted against geometric ones (both divided by their noise scale).
    const double colour_scale =
        options.colour_weight * (spacing * spacing) / (options.colour_sigma * options.colour_sigma);
    const IcpCriteria& crit = options.icp.criteria;
    std::vector<int> moved_iterations(nv, 0);
    std::vector<char> converged(nv, 0);
    const std::size_t dim = 6 * nv;
    Eigen::MatrixXd h(dim, dim);
    Eigen::VectorXd g(dim);
    std::vector<std::size_t> matched(nv);
    std::vector<double> extent(nv);  // max distance of a view's points from the centre

    // Joint rounds from the current poses: all rounds (coarse to fine) from the initial poses,
    // the finest two (at most 10 iterations each) after the pairwise stage and the pose graph.
    auto joint_rounds = [&](bool after_pairwise) {
        const int first_round =
            after_pairwise ? std::max(0, options.rounds - std::min(options.rounds, 2)) : 0;
        for (int round = first_round; round < options.rounds; ++round) {
            const double dmax = result.max_distances_m[round];
            const double k = options.icp.kernel_scale * dmax;
            bool round_converged = false;
            const int max_it =
                options.pairwise ? std::min(crit.max_iterations, 10) : crit.max_iterations;
            for (int it = 0; it < max_it; ++it) {
                match_all(dmax);
                // Global centre for the rotation parametrisation (conditioning).
                Eigen::Vector3d centre = Eigen::Vector3d::Zero();
                for (const auto& p : world) centre += p;
                centre /= static_cast<double>(total);
                std::fill(extent.begin(), extent.end(), 0.0);
                for (std::size_t a = 0; a < total; ++a)
                    extent[owner[a]] = std::max(extent[owner[a]], (world[a] - centre).norm());

                // Ordered assembly of the joint normal equations.
                h.setZero();
                g.setZero();
                std::fill(matched.begin(), matched.end(), 0);
                for (std::size_t a = 0; a < total; ++a) {
                    const Match& m = match[a];
                    if (m.other < 0) continue;
                    const std::size_t b = static_cast<std::size_t>(m.other);
                    const std::size_t i = owner[a], j = owner[b];
                    ++matched[i];
                    const double w = internal::robust_weight(kernel, m.residual, k);
                    if (w <= 0) continue;
                    const Eigen::Vector3d& n = world_n[b];
                    Eigen::Matrix<double, 6, 1> ji, jj;
                    ji.head<3>() = (world[a] - centre).cross(n);
                    ji.tail<3>() = n;
                    jj.head<3>() = -(world[b] - centre).cross(n);
                    jj.tail<3>() = -n;
                    h.block<6, 6>(6 * i, 6 * i).noalias() += w * ji * ji.transpose();
                    h.block<6, 6>(6 * j, 6 * j).noalias() += w * jj * jj.transpose();
                    h.block<6, 6>(6 * i, 6 * j).noalias() += w * ji * jj.transpose();
                    h.block<6, 6>(6 * j, 6 * i).noalias() += w * jj * ji.transpose();
                    g.segment<6>(6 * i) += (w * m.residual) * ji;
                    g.segment<6>(6 * j) += (w * m.residual) * jj;
                    if (!use_colour) continue;
                    // Park et al.'s colour term, in the same units as the geometric one.
                    const Eigen::Vector3d& d = world_d[b];
                    const double rc = intensity[b] + d.dot(world[a] - world[b]) - intensity[a];
                    const double wc = w * colour_scale *
                                      internal::robust_weight(1, rc, 2.0 * options.colour_sigma);
                    ji.head<3>() = (world[a] - centre).cross(d);
                    ji.tail<3>() = d;
                    jj.head<3>() = -(world[b] - centre).cross(d);
                    jj.tail<3>() = -d;
                    h.block<6, 6>(6 * i, 6 * i).noalias() += wc * ji * ji.transpose();
                    h.block<6, 6>(6 * j, 6 * j).noalias() += wc * jj * jj.transpose();
                    h.block<6, 6>(6 * i, 6 * j).noalias() += wc * ji * jj.transpose();
                    h.block<6, 6>(6 * j, 6 * i).noalias() += wc * jj * ji.transpose();
                    g.segment<6>(6 * i) += (wc * rc) * ji;
                    g.segment<6>(6 * j) += (wc * rc) * jj;
                }

                // Free views: all but the gauge and those with too few matches this iteration.
                std::vector<std::size_t> active;
                for (std::size_t v = 0; v < nv; ++v)
                    if (v != options.fixed_view && matched[v] >= kMinMatches) active.push_back(v);
                if (active.empty()) break;
                const Eigen::Index m = static_cast<Eigen::Index>(6 * active.size());
                Eigen::MatrixXd hr(m, m);
                Eigen::VectorXd gr(m);
                for (std::size_t x = 0; x < active.size(); ++x) {
                    gr.segment<6>(6 * x) = g.segment<6>(6 * active[x]);
                    for (std::size_t y = 0; y < active.size(); ++y)
                        hr.block<6, 6>(6 * x, 6 * y) = h.block<6, 6>(6 * active[x], 6 * active[y]);
                }
                // Tiny Levenberg damping keeps views that slide along a symmetric surface bounded.
                const double damping = 1e-9 * std::max(hr.diagonal().maxCoeff(), 1e-300);
                hr.diagonal().array() += damping;
                Eigen::LDLT<Eigen::MatrixXd> ldlt(hr);
                if (ldlt.info() != Eigen::Success) break;
                const Eigen::VectorXd x = ldlt.solve(-gr);
                if (!x.allFinite()) break;

                // Largest displacement of any working point by this step (bound).
                double max_motion = 0;
                for (std::size_t a = 0; a < active.size(); ++a) {
                    const Eigen::Matrix<double, 6, 1> step = x.segment<6>(6 * a);
                    Working& w = work[active[a]];
                    w.pose = orthonormalized(internal::rigid_update(step, centre) * w.pose);
                    ++moved_iterations[active[a]];
                    max_motion = std::max(max_motion, step.head<3>().norm() * extent[active[a]] +
                                                          step.tail<3>().norm());
                }
                ++result.iterations;
                if (max_motion <= options.min_motion_spacing * spacing) {
                    round_converged = true;
                    break;
                }
            }
            if (round == options.rounds - 1)
                for (std::size_t v = 0; v < nv; ++v) converged[v] = round_converged ? 1 : 0;
            if (!report_progress(progress, 0.35 + 0.55 * (round + 1) / options.rounds))
                throw AlgorithmError("align_views: cancelled");
        }
    };
    // Mean share of working points matched to another view at the finest distance.
    auto overlap_score = [&]() {
        match_all(result.max_distances_m.back());
        std::size_t m = 0;
        for (const Match& x : match) m += x.other >= 0 ? 1 : 0;
        return static_cast<double>(m) / static_cast<double>(std::max<std::size_t>(total, 1));
    };

    if (options.pairwise && poses_known) {
        // Safety net: on smooth, nearly symmetric shapes pairs can slide where the joint
        // rounds, pinned from both sides, do not. Run those from the initial poses too and keep
        // them when they match clearly more points (the pairs then show their disagreement).
        joint_rounds(true);
        const double pair_score = overlap_score();
        std::vector<Pose> pair_result(nv);
        for (std::size_t v = 0; v < nv; ++v) pair_result[v] = work[v].pose;
        const auto counters = std::make_pair(moved_iterations, converged);
        const int pair_iterations = result.iterations;
        for (std::size_t v = 0; v < nv; ++v) work[v].pose = work[v].initial;
        std::fill(moved_iterations.begin(), moved_iterations.end(), 0);
        joint_rounds(false);
        const double joint_score = overlap_score();
        result.joint_only_fitness = joint_score;
        result.pairwise_fitness = pair_score;
        if (joint_score > pair_score + 0.05) {
            result.start = "initial poses (joint rounds matched more than the pairwise stage)";
        } else {
            for (std::size_t v = 0; v < nv; ++v) work[v].pose = pair_result[v];
            std::tie(moved_iterations, converged) = counters;
            result.iterations = pair_iterations;
            result.start = "pairwise stage and pose graph";
        }
    } else {
        joint_rounds(options.pairwise);
        result.start = options.pairwise ? "pairwise stage and pose graph" : "initial poses";
    }

    // Final per-view evaluation at the finest distance.
    match_all(result.max_distances_m.back());
    std::vector<double> sq_sum(nv, 0.0);
    std::fill(matched.begin(), matched.end(), 0);
    for (std::size_t a = 0; a < total; ++a) {
        if (match[a].other < 0) continue;
        ++matched[owner[a]];
        sq_sum[owner[a]] += match[a].sq_dist;
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
    const std::vector<std::size_t> order = ring_order(nv, result.pairs);
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
            const PairAlignment& p = result.pairs[pair_index(result.pairs, a, b)];
            before = before * relative(p.target_from_source, p.target, a);
        }
        const std::size_t last = order[nv - 1], first = order[0];
        const PairAlignment& closing = result.pairs[pair_index(result.pairs, last, first)];
        const Pose after = relative(closing.target_from_source, closing.target, last).inverse() *
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
        va.rotation_change_deg = rotation_error_deg(va.correction, Pose::Identity());
        // Translation of the view's own points (its centroid), not of the world origin.
        const Eigen::Vector3d c0 = w.initial * w.reg.centroid;
        va.translation_change_m = (va.correction * c0 - c0).norm();
        va.pairs = view_pairs[v];
        va.ring_rotation_deg = ring_rot[v];
        va.ring_translation_m = ring_trans[v];
        const bool moved_far = va.rotation_change_deg > options.max_rotation_deg ||
                               va.translation_change_m > options.max_translation_m;
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
        } else if (!options.pairwise && moved_far) {
            va.verdict = Verdict::kFail;
            va.reason = "moved too far from its initial pose";
        } else if (ring_disagrees) {
            va.verdict = Verdict::kWarn;
            va.reason = "its pairs disagree with the final poses";
        } else if (va.fitness < options.warn_fitness) {
            va.verdict = Verdict::kWarn;
            va.reason = "small overlap";
        } else if (moved_far && poses_known) {
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

void apply_alignment(std::vector<PointCloud>& views, const MultiViewResult& result) {
    RGBD_CHECK(views.size() == result.views.size(),
               "apply_alignment: " + std::to_string(views.size()) + " views but " +
                   std::to_string(result.views.size()) + " results");
    for (std::size_t v = 0; v < views.size(); ++v) {
        PointCloud& view = views[v];
        const ViewAlignment& va = result.views[v];
        if (view.view.frame == ViewFrame::kSensor) {
            view.view.world_from_sensor = va.world_from_sensor;
            to_world_frame(view);
        } else {
            transform(view, va.correction);
            if (view.view.world_from_sensor) view.view.world_from_sensor = va.world_from_sensor;
        }
    }
}

}  // namespace rgbd::registration
