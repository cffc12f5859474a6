// Joint multi-view point-to-plane refinement (see icp.hpp for the contract).
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <string>

#include "algorithms/internal/icp_math.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/normals/estimate_normals.hpp"
#include "algorithms/registration/icp.hpp"
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

/// Working copy of one view: points and normals in the frame of its initial pose `initial`.
struct Working {
    std::vector<Eigen::Vector3d> xyz, normals;
    Pose initial = Pose::Identity();                     // world_from_working at the start
    Pose pose = Pose::Identity();                        // current world_from_working
    bool oriented = true;                                // normals point towards a known sensor
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // working frame
};

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
        r["views"].push_back(j);
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
        std::vector<double> s(nv);
        for (std::size_t v = 0; v < nv; ++v)
            s[v] = sampling::robust_spacing(measured[v]->points, 2000);
        std::nth_element(s.begin(), s.begin() + nv / 2, s.end());
        spacing = s[nv / 2];
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

    // Working copies: down-sampled, normals towards the sensor.
    std::vector<Working> work(nv);
    normals::NormalOptions nopt;
    nopt.k = options.normal_k;
    bool all_oriented = true;
    for (std::size_t v = 0; v < nv; ++v) {
        PointCloud down = sampling::voxel_downsample(*measured[v], voxel);
        RGBD_CHECK(down.size() >= 3, "align_views: " + view_name(views[v]) +
                                         " has fewer than 3 points after down-sampling");
        const Report nrep = normals::estimate_normals(down, nopt);
        Working& w = work[v];
        w.oriented = nrep["orientation"] == "sensor";
        all_oriented = all_oriented && w.oriented;
        w.initial = views[v].view.frame == ViewFrame::kSensor ? *views[v].view.world_from_sensor
                                                              : Pose::Identity();
        w.pose = w.initial;
        for (auto idx : down.points) {
            w.xyz.push_back(to_eigen(down.points.point(idx)));
            w.normals.push_back(to_eigen(down.points.normal(idx)));
            w.centroid += w.xyz.back();
        }
        w.centroid /= static_cast<double>(w.xyz.size());
        if (!report_progress(progress, 0.1 * (v + 1) / nv))
            throw AlgorithmError("align_views: cancelled");
    }

    // Flattened union: offsets per view, owner per point.
    std::vector<std::size_t> offset(nv + 1, 0);
    for (std::size_t v = 0; v < nv; ++v) offset[v + 1] = offset[v] + work[v].xyz.size();
    const std::size_t total = offset[nv];
    std::vector<std::uint32_t> owner(total);
    for (std::size_t v = 0; v < nv; ++v)
        std::fill(owner.begin() + offset[v], owner.begin() + offset[v + 1], v);
    std::vector<Eigen::Vector3d> world(total), world_n(total);
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
            for (std::size_t i = 0; i < work[v].xyz.size(); ++i) {
                world[offset[v] + i] = pose * work[v].xyz[i];
                world_n[offset[v] + i] = rot * work[v].normals[i];
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

    const IcpCriteria& crit = options.icp.criteria;
    std::vector<int> moved_iterations(nv, 0);
    std::vector<char> converged(nv, 0);
    const std::size_t dim = 6 * nv;
    Eigen::MatrixXd h(dim, dim);
    Eigen::VectorXd g(dim);
    std::vector<std::size_t> matched(nv);
    std::vector<double> extent(nv);  // max distance of a view's points from the centre

    for (int round = 0; round < options.rounds; ++round) {
        const double dmax = result.max_distances_m[round];
        const double k = options.icp.kernel_scale * dmax;
        bool round_converged = false;
        for (int it = 0; it < crit.max_iterations; ++it) {
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
                max_motion = std::max(
                    max_motion, step.head<3>().norm() * extent[active[a]] + step.tail<3>().norm());
            }
            ++result.iterations;
            if (max_motion <= options.min_motion_spacing * spacing) {
                round_converged = true;
                break;
            }
        }
        if (round == options.rounds - 1)
            for (std::size_t v = 0; v < nv; ++v) converged[v] = round_converged ? 1 : 0;
        if (!report_progress(progress, 0.1 + 0.85 * (round + 1) / options.rounds))
            throw AlgorithmError("align_views: cancelled");
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
        const std::size_t n = w.xyz.size();
        va.fitness = static_cast<double>(matched[v]) / static_cast<double>(n);
        va.inlier_rmse = matched[v] ? std::sqrt(sq_sum[v] / matched[v]) : 0.0;
        va.iterations = moved_iterations[v];
        va.converged = converged[v] != 0;
        va.rotation_change_deg = rotation_error_deg(va.correction, Pose::Identity());
        // Translation of the view's own points (its centroid), not of the world origin.
        const Eigen::Vector3d c0 = w.initial * w.centroid;
        va.translation_change_m = (va.correction * c0 - c0).norm();
        if (va.fitness < options.fail_fitness ||
            va.rotation_change_deg > options.max_rotation_deg ||
            va.translation_change_m > options.max_translation_m)
            va.verdict = Verdict::kFail;
        else if (va.fitness < options.warn_fitness)
            va.verdict = Verdict::kWarn;
        else
            va.verdict = Verdict::kPass;
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
