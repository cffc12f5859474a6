// Pairwise stage of align_views (docs/algorithms.md §6): pair selection, pairwise point-to-plane
// ICP with a colour term from the initial pose and from FPFH + RANSAC hypotheses (pairs in
// parallel, TBB; each view's kd-tree built once, see align_stages.hpp), the choice between
// candidates by loop closure on a ring, and the pose graph.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/registration/align_stages.hpp"
#include "algorithms/registration/global_registration.hpp"
#include "algorithms/registration/pose_graph.hpp"
#include "algorithms/sampling/voxel_downsample.hpp"
#include "toolkit/error.hpp"

namespace rgbd::registration::detail {

/// Rotation angle and translation at point c (working frame of the source) of the motion d.
std::pair<double, double> motion_at(const Pose& d, const Eigen::Vector3d& c) {
    return {rotation_error_deg(d, Pose::Identity()), (d * c - c).norm()};
}

/// Pairs of the pairwise stage (see MultiViewOptions::pairwise). `by_direction`: the views'
/// viewing directions are known and tell something (not all the same); else stream order.
static std::vector<std::pair<std::size_t, std::size_t>> select_pairs(
    const std::vector<Working>& work, const MultiViewOptions& o, bool by_direction) {
    const std::size_t nv = work.size();
    std::set<std::pair<std::size_t, std::size_t>> unique;
    auto add = [&](std::size_t a, std::size_t b) {
        const auto p = std::minmax(a, b);
        unique.emplace(p.first, p.second);
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
    return {unique.begin(), unique.end()};  // sorted
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

void pairwise_stage(std::vector<Working>& work, const MultiViewOptions& options,
                    const PairwiseInputs& in, MultiViewResult& result, std::vector<int>& view_pairs,
                    std::vector<bool>& tied, const Progress& progress) {
    const std::size_t nv = work.size();
    const std::vector<const PointCloud*>& measured = *in.measured;
    const internal::PairIcpSettings& pset = in.icp;
    const double voxel = in.voxel, spacing = in.spacing, eval_distance = in.eval_distance;
    Stopwatch pair_watch;
    normals::NormalOptions nopt;
    nopt.k = in.normal_k;
    const auto selected = select_pairs(work, options, in.poses_known);
    result.pairs.resize(selected.size());
    // Candidate outcomes per pair: from the initial pose, and from the global hypothesis
    // when it ends elsewhere (and within the prior's bounds). Index 0 = the default choice.
    struct Candidate {
        internal::PairIcpOutcome outcome;
        const char* method;
    };
    std::vector<std::vector<Candidate>> cands(selected.size());
    // Whether pair k tries a global hypothesis: unless the poses are known and bound the pair and
    // the initial start's result stayed within the bounds and passes (MultiViewOptions::
    // global_always).
    std::vector<char> try_global(selected.size(), 0);
    const auto bounded_pair = [&](std::size_t a, std::size_t b) {
        return work[a].direction && work[b].direction && options.max_prior_rotation_deg < 180;
    };
    tbb::parallel_for(std::size_t{0}, selected.size(), [&](std::size_t k) {
        const auto [a, b] = selected[k];  // target a, source b
        PairAlignment& pa = result.pairs[k];
        pa.target = a;
        pa.source = b;
        const Pose prior = work[a].initial.inverse() * work[b].initial;
        const bool bounded = bounded_pair(a, b);
        const Eigen::Vector3d& c = work[b].reg.centroid;
        // A result that left the calibration's bounds slid into a wrong basin (a head is
        // nearly a surface of revolution).
        auto within = [&](const Pose& z) {
            if (!bounded) return true;
            const auto [prot, ptrans] = motion_at(prior.inverse() * z, c);
            return prot <= options.max_prior_rotation_deg &&
                   ptrans <= options.max_prior_translation_m;
        };
        // From the initial pose: the full coarse-to-fine schedule, and (when the poses are
        // known) the finest two distances alone, which cannot slide far on smooth, nearly
        // symmetric shapes; the one with more colour-consistent matches within the bounds.
        internal::PairIcpSettings fine = pset;
        fine.distances.assign(
            pset.distances.end() - std::min<std::size_t>(2, pset.distances.size()),
            pset.distances.end());
        internal::PairIcpOutcome first =
            internal::pair_icp(work[b].reg, work[a].reg, *work[a].tree, prior, pset, eval_distance);
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
        // The pair verdict's PASS test (see fill() below) on the initial start's result.
        const double smaller =
            static_cast<double>(std::min(work[a].reg.xyz.size(), work[b].reg.xyz.size()));
        const bool passes =
            first.correspondences >= 30 &&
            std::min(1.0, double(first.correspondences) / smaller) >= options.pair_warn_fitness;
        try_global[k] = options.global_registration && (options.global_always || !in.poses_known ||
                                                        !bounded || !first_ok || !passes)
                            ? 1
                            : 0;
        cands[k].push_back({std::move(first), "initial"});
    });

    // Feature copies (coarser voxel) for the global hypotheses, of the views of the pairs
    // that try one.
    std::vector<char> needs_features(nv, 0);
    for (std::size_t k = 0; k < selected.size(); ++k)
        if (try_global[k])
            needs_features[selected[k].first] = needs_features[selected[k].second] = 1;
    std::vector<std::vector<Eigen::Vector3d>> fxyz(nv);
    std::vector<std::vector<Fpfh>> feats(nv);
    if (options.global_registration) {
        const double fvoxel = options.feature_voxel_factor * voxel;
        tbb::parallel_for(std::size_t{0}, nv, [&](std::size_t v) {
            if (!needs_features[v]) return;
            PointCloud fc = sampling::voxel_downsample(*measured[v], fvoxel);
            if (fc.size() < 10) return;
            normals::estimate_normals(fc, nopt);
            std::vector<Eigen::Vector3d> fn;
            for (auto idx : fc.points) {
                fxyz[v].push_back(to_eigen(fc.points.point(idx)));
                fn.push_back(to_eigen(fc.points.normal(idx)).normalized());
            }
            feats[v] = compute_fpfh(fxyz[v], fn, options.feature_radius_factor * fvoxel);
        });
    }
    // Global hypotheses of the pairs that try one.
    tbb::parallel_for(std::size_t{0}, selected.size(), [&](std::size_t k) {
        const auto [a, b] = selected[k];  // target a, source b
        if (!try_global[k] || feats[a].empty() || feats[b].empty()) return;
        PairAlignment& pa = result.pairs[k];
        pa.global_tried = true;
        const Pose prior = work[a].initial.inverse() * work[b].initial;
        const bool bounded = bounded_pair(a, b);
        const Eigen::Vector3d& c = work[b].reg.centroid;
        auto within = [&](const Pose& z) {
            if (!bounded) return true;
            const auto [prot, ptrans] = motion_at(prior.inverse() * z, c);
            return prot <= options.max_prior_rotation_deg &&
                   ptrans <= options.max_prior_translation_m;
        };
        auto& list = cands[k];
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
        internal::PairIcpOutcome g = internal::pair_icp(work[b].reg, work[a].reg, *work[a].tree,
                                                        rr.target_from_source, pset, eval_distance);
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
            std::min(1.0, static_cast<double>(best.correspondences) /
                              static_cast<double>(std::min(work[pa.target].reg.xyz.size(),
                                                           work[pa.source].reg.xyz.size())));
        pa.inlier_rmse = best.inlier_rmse;
        pa.colour_rmse = best.colour_rmse;
        pa.reason.clear();
        if (best.correspondences < 30 || pa.fitness < options.pair_fail_fitness) {
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

}  // namespace rgbd::registration::detail
