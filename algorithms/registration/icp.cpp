#include "algorithms/registration/icp.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "algorithms/internal/icp_math.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "toolkit/error.hpp"

namespace rgbd::registration {

namespace {

constexpr std::size_t kChunk = 512;
constexpr double kDegToRad = M_PI / 180.0;

std::string view_name(const PointCloud& cloud) { return "view " + std::to_string(cloud.view.id); }

struct Gathered {
    std::vector<Eigen::Vector3d> xyz;
    std::vector<Eigen::Vector3d> normals;  // empty when the cloud has none
};

Gathered gather(const PointCloud& cloud, const char* role) {
    Gathered g;
    const bool normals = cloud.points.has_normal_map();
    g.xyz.reserve(cloud.size());
    if (normals) g.normals.reserve(cloud.size());
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        RGBD_CHECK(p.allFinite(), std::string("icp: ") + role + " " + view_name(cloud) +
                                      ": point " + std::to_string(g.xyz.size()) + " is not finite");
        g.xyz.push_back(p);
        if (normals) {
            const Eigen::Vector3d n = to_eigen(cloud.points.normal(idx));
            RGBD_CHECK(n.allFinite(), std::string("icp: ") + role + " " + view_name(cloud) +
                                          ": normal " + std::to_string(g.normals.size()) +
                                          " is not finite");
            const double len = n.norm();
            g.normals.push_back(len > 0 ? Eigen::Vector3d(n / len) : n);
        }
    }
    return g;
}

/// Sums of one chunk (and of the whole set after the ordered combine).
struct Sums {
    Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    double sq_dist = 0.0;   // point-to-point, matched pairs
    double sq_plane = 0.0;  // point-to-plane, matched pairs
    std::size_t matched = 0;

    void add(const Sums& o) {
        h += o.h;
        g += o.g;
        sq_dist += o.sq_dist;
        sq_plane += o.sq_plane;
        matched += o.matched;
    }
};

struct PairProblem {
    const Gathered& source;
    const Gathered& target;
    const internal::KdTree& tree;
    int kernel;
    double kernel_scale;
    double cos_gate;  // -2 disables
};

/// Matches every source point under `pose` and accumulates the normal equations about `centre`.
/// Fixed chunks written to their own slots, combined in chunk order: bit-identical for any
/// number of threads.
Sums accumulate(const PairProblem& pb, const Pose& pose, const Eigen::Vector3d& centre,
                double max_distance, std::vector<Sums>& chunk_sums) {
    const std::size_t n = pb.source.xyz.size();
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    chunk_sums.assign(chunks, Sums{});
    const double max_sq = max_distance * max_distance;
    const double k = pb.kernel_scale * max_distance;
    const Eigen::Matrix3d rot = pose.linear();
    const bool gate = pb.cos_gate > -1.5 && !pb.source.normals.empty();
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
        Sums s;
        const std::size_t end = std::min(n, (c + 1) * kChunk);
        for (std::size_t i = c * kChunk; i < end; ++i) {
            const Eigen::Vector3d p = pose * pb.source.xyz[i];
            std::uint32_t j;
            double d2;
            if (!pb.tree.nearest(p, j, d2) || d2 > max_sq) continue;
            const Eigen::Vector3d& q = pb.target.xyz[j];
            const Eigen::Vector3d& nq = pb.target.normals[j];
            if (gate && (rot * pb.source.normals[i]).dot(nq) < pb.cos_gate) continue;
            const double r = (p - q).dot(nq);
            const double w = internal::robust_weight(pb.kernel, r, k);
            ++s.matched;
            s.sq_dist += d2;
            s.sq_plane += r * r;
            if (w <= 0.0) continue;
            Eigen::Matrix<double, 6, 1> jrow;
            jrow.head<3>() = (p - centre).cross(nq);
            jrow.tail<3>() = nq;
            s.h.noalias() += w * jrow * jrow.transpose();
            s.g.noalias() += (w * r) * jrow;
        }
        chunk_sums[c] = s;
    });
    Sums total;
    for (const Sums& s : chunk_sums) total.add(s);
    return total;
}

}  // namespace

void IcpCriteria::check() const {
    RGBD_CHECK(max_iterations >= 1 && max_iterations <= 100000,
               "icp: max_iterations must be in [1, 100000]");
    RGBD_CHECK(relative_fitness >= 0 && relative_rmse >= 0 && min_rotation_deg >= 0 &&
                   min_translation_spacing >= 0,
               "icp: convergence thresholds must be non-negative");
}

void IcpOptions::check() const {
    criteria.check();
    for (double d : max_distances_m)
        RGBD_CHECK(std::isfinite(d) && d > 0, "icp: max distances must be positive");
    RGBD_CHECK(!max_distances_m.empty() || !max_distance_factors.empty(),
               "icp: give max_distances_m or max_distance_factors");
    for (double f : max_distance_factors)
        RGBD_CHECK(std::isfinite(f) && f > 0 && f < 1e4,
                   "icp: max distance factors must be in (0, 1e4)");
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m >= 0, "icp: spacing_m must be >= 0");
    RGBD_CHECK(std::isfinite(kernel_scale) && kernel_scale > 0 && kernel_scale <= 100,
               "icp: kernel_scale must be in (0, 100]");
    RGBD_CHECK(max_normal_angle_deg > 0 && max_normal_angle_deg <= 360,
               "icp: max_normal_angle_deg must be in (0, 360]");
}

Report AlignResult::to_json() const {
    Report r;
    r["target_from_source"] = pose_to_3x4(target_from_source);
    r["fitness"] = fitness;
    r["inlier_rmse_m"] = inlier_rmse;
    r["plane_rmse_m"] = plane_rmse;
    r["correspondences"] = correspondences;
    r["iterations"] = iterations;
    r["converged"] = converged;
    return r;
}

AlignResult align_pair(const PointCloud& source, const PointCloud& target,
                       const Pose& initial_target_from_source, const IcpOptions& options) {
    options.check();
    RGBD_CHECK(!source.empty(), "icp: source " + view_name(source) + " is empty");
    RGBD_CHECK(!target.empty(), "icp: target " + view_name(target) + " is empty");
    RGBD_CHECK(target.points.has_normal_map(),
               "icp: target " + view_name(target) + " has no normals; estimate them first");
    RGBD_CHECK(initial_target_from_source.matrix().allFinite(),
               "icp: initial pose of source " + view_name(source) + " is not finite");
    const Gathered src = gather(source, "source");
    const Gathered tgt = gather(target, "target");

    double spacing = options.spacing_m;
    std::vector<double> distances = options.max_distances_m;
    if (spacing <= 0 && (distances.empty() || options.criteria.min_translation_spacing > 0))
        spacing = src.xyz.size() >= 2 ? sampling::robust_spacing(source.points) : 0.0;
    if (distances.empty()) {
        RGBD_CHECK(spacing > 0,
                   "icp: source " + view_name(source) + " has zero spacing; give max_distances_m");
        for (double f : options.max_distance_factors) distances.push_back(f * spacing);
    }

    const internal::KdTree tree(tgt.xyz);
    const PairProblem pb{src,
                         tgt,
                         tree,
                         static_cast<int>(options.kernel),
                         options.kernel_scale,
                         options.max_normal_angle_deg >= 180
                             ? -2.0
                             : std::cos(options.max_normal_angle_deg * kDegToRad)};
    Eigen::Vector3d src_centroid = Eigen::Vector3d::Zero();
    for (const auto& p : src.xyz) src_centroid += p;
    src_centroid /= static_cast<double>(src.xyz.size());

    AlignResult result;
    Pose pose = initial_target_from_source;
    std::vector<Sums> chunk_sums;
    const IcpCriteria& crit = options.criteria;
    const double n = static_cast<double>(src.xyz.size());
    for (double dmax : distances) {
        bool stage_converged = false;
        double prev_fitness = -1, prev_rmse = -1;
        for (int it = 0; it < crit.max_iterations; ++it) {
            const Eigen::Vector3d centre = pose * src_centroid;
            const Sums s = accumulate(pb, pose, centre, dmax, chunk_sums);
            const double fitness = s.matched / n;
            const double rmse = s.matched ? std::sqrt(s.sq_dist / s.matched) : 0.0;
            if (prev_fitness >= 0 &&
                std::abs(fitness - prev_fitness) <=
                    crit.relative_fitness * std::max(fitness, 1e-300) &&
                std::abs(rmse - prev_rmse) <= crit.relative_rmse * std::max(rmse, 1e-300)) {
                stage_converged = true;
                break;
            }
            prev_fitness = fitness;
            prev_rmse = rmse;
            if (s.matched < 6) break;
            Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(s.h);
            if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 1e-14 * s.h.trace())
                break;
            const Eigen::Matrix<double, 6, 1> x = ldlt.solve(-s.g);
            if (!x.allFinite()) break;
            pose = orthonormalized(internal::rigid_update(x, centre) * pose);
            ++result.iterations;
            if (x.head<3>().norm() <= crit.min_rotation_deg * kDegToRad &&
                x.tail<3>().norm() <= crit.min_translation_spacing * spacing) {
                stage_converged = true;
                break;
            }
        }
        result.converged = stage_converged;
    }

    // Final evaluation at the final pose and the finest distance.
    const Sums s = accumulate(pb, pose, pose * src_centroid, distances.back(), chunk_sums);
    result.target_from_source = pose;
    result.correspondences = s.matched;
    result.fitness = s.matched / n;
    result.inlier_rmse = s.matched ? std::sqrt(s.sq_dist / s.matched) : 0.0;
    result.plane_rmse = s.matched ? std::sqrt(s.sq_plane / s.matched) : 0.0;
    return result;
}

}  // namespace rgbd::registration
