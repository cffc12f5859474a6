// Pose-graph optimisation (see pose_graph.hpp).
#include "algorithms/registration/pose_graph.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>

#include "toolkit/error.hpp"

namespace rgbd::registration {

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// Small motion of a 6-vector (rotation vector, translation).
Pose exp6(const Vec6& d) {
    Pose p = Pose::Identity();
    const double angle = d.head<3>().norm();
    if (angle > 0) p.linear() = Eigen::AngleAxisd(angle, d.head<3>() / angle).toRotationMatrix();
    p.translation() = d.tail<3>();
    return p;
}

Vec6 log6(const Pose& p) {
    const Eigen::AngleAxisd aa(p.linear());
    Vec6 v;
    v.head<3>() = aa.angle() * aa.axis();
    v.tail<3>() = p.translation();
    return v;
}

Vec6 edge_error(const Pose& xi, const Pose& xj, const Pose& z) {
    return log6(z.inverse() * xi.inverse() * xj);
}

std::vector<bool> reachable(std::size_t n, std::size_t root, const std::vector<PoseGraphEdge>& e,
                            const std::vector<bool>& active) {
    std::vector<bool> seen(n, false);
    seen[root] = true;
    for (bool changed = true; changed;) {
        changed = false;
        for (std::size_t k = 0; k < e.size(); ++k) {
            if (!active[k]) continue;
            if (seen[e[k].source] != seen[e[k].target]) {
                seen[e[k].source] = seen[e[k].target] = true;
                changed = true;
            }
        }
    }
    return seen;
}

double total_cost(const std::vector<Pose>& x, const std::vector<PoseGraphEdge>& e,
                  const std::vector<bool>& active) {
    double c = 0;
    for (std::size_t k = 0; k < e.size(); ++k) {
        if (!active[k]) continue;
        const Vec6 r = edge_error(x[e[k].target], x[e[k].source], e[k].target_from_source);
        c += r.dot(e[k].information * r);
    }
    return c;
}

/// Levenberg-Marquardt over the connected, non-fixed nodes.
int solve(std::vector<Pose>& x, const std::vector<PoseGraphEdge>& e,
          const std::vector<bool>& active, const std::vector<bool>& connected, std::size_t fixed,
          int max_iterations) {
    const std::size_t n = x.size();
    std::vector<long> slot(n, -1);
    long m = 0;
    for (std::size_t v = 0; v < n; ++v)
        if (connected[v] && v != fixed) slot[v] = m++;
    if (m == 0) return 0;
    double lambda = 1e-6;
    double cost = total_cost(x, e, active);
    int it = 0;
    const double eps = 1e-7;
    for (; it < max_iterations; ++it) {
        Eigen::MatrixXd h = Eigen::MatrixXd::Zero(6 * m, 6 * m);
        Eigen::VectorXd g = Eigen::VectorXd::Zero(6 * m);
        for (std::size_t k = 0; k < e.size(); ++k) {
            if (!active[k]) continue;
            const std::size_t i = e[k].target, j = e[k].source;
            const Vec6 r = edge_error(x[i], x[j], e[k].target_from_source);
            Mat6 ji, jj;
            for (int d = 0; d < 6; ++d) {
                Vec6 step = Vec6::Zero();
                step(d) = eps;
                ji.col(d) = (edge_error(x[i] * exp6(step), x[j], e[k].target_from_source) -
                             edge_error(x[i] * exp6(-step), x[j], e[k].target_from_source)) /
                            (2 * eps);
                jj.col(d) = (edge_error(x[i], x[j] * exp6(step), e[k].target_from_source) -
                             edge_error(x[i], x[j] * exp6(-step), e[k].target_from_source)) /
                            (2 * eps);
            }
            const Mat6& om = e[k].information;
            const long si = slot[i], sj = slot[j];
            if (si >= 0) {
                h.block<6, 6>(6 * si, 6 * si) += ji.transpose() * om * ji;
                g.segment<6>(6 * si) += ji.transpose() * om * r;
            }
            if (sj >= 0) {
                h.block<6, 6>(6 * sj, 6 * sj) += jj.transpose() * om * jj;
                g.segment<6>(6 * sj) += jj.transpose() * om * r;
            }
            if (si >= 0 && sj >= 0) {
                h.block<6, 6>(6 * si, 6 * sj) += ji.transpose() * om * jj;
                h.block<6, 6>(6 * sj, 6 * si) += jj.transpose() * om * ji;
            }
        }
        bool improved = false;
        for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
            Eigen::MatrixXd hl = h;
            hl.diagonal() += lambda * (h.diagonal().array() + 1e-12).matrix();
            const Eigen::VectorXd dx = hl.ldlt().solve(-g);
            if (!dx.allFinite()) {
                lambda *= 10;
                continue;
            }
            std::vector<Pose> trial = x;
            for (std::size_t v = 0; v < n; ++v)
                if (slot[v] >= 0)
                    trial[v] = orthonormalized(x[v] * exp6(dx.segment<6>(6 * slot[v])));
            const double c = total_cost(trial, e, active);
            if (c <= cost) {
                const double rel = (cost - c) / std::max(cost, 1e-300);
                x = std::move(trial);
                cost = c;
                lambda = std::max(lambda / 10, 1e-12);
                improved = true;
                if (rel < 1e-10) return it + 1;
            } else {
                lambda *= 10;
            }
        }
        if (!improved) break;
    }
    return it;
}

}  // namespace

void PoseGraphOptions::check() const {
    check_range("pose graph: max_iterations", max_iterations, Range::closed(1, 10000));
    RGBD_CHECK(prune_rotation_deg > 0 && prune_translation_m > 0,
               "pose graph: prune thresholds must be positive");
}

EdgeResidual edge_residual(const std::vector<Pose>& poses, const PoseGraphEdge& edge) {
    const Pose d =
        edge.target_from_source.inverse() * poses[edge.target].inverse() * poses[edge.source];
    return {rotation_error_deg(d, Pose::Identity()), d.translation().norm()};
}

PoseGraphResult optimise_pose_graph(const std::vector<Pose>& initial,
                                    const std::vector<PoseGraphEdge>& edges,
                                    const PoseGraphOptions& options) {
    options.check();
    const std::size_t n = initial.size();
    RGBD_CHECK(options.fixed_node < n,
               "pose graph: fixed node " + std::to_string(options.fixed_node) + " out of range");
    for (const Pose& p : initial)
        RGBD_CHECK(p.matrix().allFinite(), "pose graph: an initial pose is not finite");
    std::vector<bool> active(edges.size());
    for (std::size_t k = 0; k < edges.size(); ++k) {
        const auto& e = edges[k];
        RGBD_CHECK(e.source < n && e.target < n && e.source != e.target,
                   "pose graph: edge " + std::to_string(k) + " has bad node indices");
        RGBD_CHECK(e.target_from_source.matrix().allFinite() && e.information.allFinite(),
                   "pose graph: edge " + std::to_string(k) + " is not finite");
        active[k] = e.active;
    }
    PoseGraphResult out;
    out.poses = initial;
    const std::vector<bool> connected0 = reachable(n, options.fixed_node, edges, active);
    out.initial_cost = total_cost(out.poses, edges, active);
    for (;;) {
        out.iterations +=
            solve(out.poses, edges, active, connected0, options.fixed_node, options.max_iterations);
        // Worst edge over the thresholds whose removal keeps every node connected.
        long worst = -1;
        double worst_score = 1.0;
        for (std::size_t k = 0; k < edges.size(); ++k) {
            if (!active[k]) continue;
            const EdgeResidual r = edge_residual(out.poses, edges[k]);
            const double score = std::max(r.rotation_deg / options.prune_rotation_deg,
                                          r.translation_m / options.prune_translation_m);
            if (score <= worst_score) continue;
            std::vector<bool> without = active;
            without[k] = false;
            if (reachable(n, options.fixed_node, edges, without) != connected0) continue;
            worst = static_cast<long>(k);
            worst_score = score;
        }
        if (worst < 0) break;
        active[worst] = false;
    }
    out.final_cost = total_cost(out.poses, edges, active);
    out.active = active;
    out.connected = connected0;
    for (const auto& e : edges) out.residuals.push_back(edge_residual(out.poses, e));
    return out;
}

}  // namespace rgbd::registration
