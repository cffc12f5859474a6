// Pairwise point-to-plane ICP with a colour term on plain arrays (see internal/pair_icp.hpp).
#include "algorithms/internal/pair_icp.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "algorithms/internal/icp_math.hpp"

namespace rgbd::internal {

namespace {

constexpr std::size_t kChunk = 512;
constexpr std::size_t kMaxGradientNeighbours = 64;
constexpr std::uint32_t kNoHint = 0xffffffffu;

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

struct Sums {
    Mat6 h = Mat6::Zero();
    Vec6 g = Vec6::Zero();
    Mat6 info = Mat6::Zero();
    double sq_dist = 0.0, sq_plane = 0.0, sq_colour = 0.0;
    std::size_t matched = 0, consistent = 0;
    void add(const Sums& o) {
        h += o.h;
        g += o.g;
        info += o.info;
        sq_dist += o.sq_dist;
        sq_plane += o.sq_plane;
        sq_colour += o.sq_colour;
        matched += o.matched;
        consistent += o.consistent;
    }
};

/// Matches every source point under `pose`; accumulates the normal equations about `centre`
/// (solve = true) or the evaluation sums and information (solve = false). Fixed chunks,
/// ordered combine: identical for any thread count.
Sums accumulate(const RegCloud& src, const RegCloud& tgt, const KdTree& tree, const Pose& pose,
                const Eigen::Vector3d& centre, double dmax, const PairIcpSettings& s, bool solve,
                std::size_t stride, std::vector<std::uint32_t>& hint,
                std::vector<Sums>& chunk_sums) {
    const std::size_t n = src.xyz.size();
    if (hint.size() != n) hint.assign(n, kNoHint);
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    chunk_sums.assign(chunks, Sums{});
    const double max_sq = dmax * dmax;
    const double k = s.kernel_scale * dmax;
    const Eigen::Matrix3d rot = pose.linear();
    const bool gate = s.cos_gate > -1.5 && !src.normals.empty();
    const bool signed_gate = src.oriented && tgt.oriented;
    const bool colour = s.colour_weight > 0 && src.has_colour() && tgt.has_colour() &&
                        tgt.gradient.size() == tgt.xyz.size();
    const double wg = 1.0 / (s.geometric_sigma * s.geometric_sigma);
    const double wc = s.colour_weight / (s.colour_sigma * s.colour_sigma);
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
        Sums sum;
        const std::size_t end = std::min(n, (c + 1) * kChunk);
        for (std::size_t i = c * kChunk; i < end; i += stride) {
            const Eigen::Vector3d p = pose * src.xyz[i];
            std::uint32_t j;
            double d2;
            // The previous match bounds the nearest distance: a much smaller search.
            double bound = max_sq;
            if (hint[i] != kNoHint) {
                const double dh = (p - tgt.xyz[hint[i]]).squaredNorm();
                if (dh < bound) bound = dh * (1.0 + 1e-9) + 1e-300;
            }
            if (!tree.nearest_within(p, bound, j, d2)) {
                hint[i] = kNoHint;
                continue;
            }
            hint[i] = j;
            if (d2 > max_sq) continue;
            const Eigen::Vector3d& q = tgt.xyz[j];
            const Eigen::Vector3d& nq = tgt.normals[j];
            if (gate) {
                const double cosang = (rot * src.normals[i]).dot(nq);
                if ((signed_gate ? cosang : std::abs(cosang)) < s.cos_gate) continue;
            }
            const double r = (p - q).dot(nq);
            double rc = 0.0;
            if (colour) rc = tgt.intensity[j] + tgt.gradient[j].dot(p - q) - src.intensity[i];
            ++sum.matched;
            sum.sq_dist += d2;
            sum.sq_plane += r * r;
            sum.sq_colour += rc * rc;
            if (!colour || std::abs(rc) <= 3.0 * s.colour_sigma) ++sum.consistent;
            if (!solve) {
                const Eigen::Vector3d& ps = src.xyz[i];
                Eigen::Matrix<double, 3, 6> gm;
                gm << 0, ps.z(), -ps.y(), 1, 0, 0,  //
                    -ps.z(), 0, ps.x(), 0, 1, 0,    //
                    ps.y(), -ps.x(), 0, 0, 0, 1;
                sum.info.noalias() += gm.transpose() * gm;
                continue;
            }
            const double w = robust_weight(s.kernel, r, k);
            if (w <= 0.0) continue;
            Vec6 jr;
            jr.head<3>() = (p - centre).cross(nq);
            jr.tail<3>() = nq;
            sum.h.noalias() += (w * wg) * jr * jr.transpose();
            sum.g.noalias() += (w * wg * r) * jr;
            if (colour) {
                const Eigen::Vector3d& d = tgt.gradient[j];
                const double w2 = w * wc * robust_weight(1, rc, 2.0 * s.colour_sigma);
                Vec6 jc;
                jc.head<3>() = (p - centre).cross(d);
                jc.tail<3>() = d;
                sum.h.noalias() += w2 * jc * jc.transpose();
                sum.g.noalias() += (w2 * rc) * jc;
            }
        }
        chunk_sums[c] = sum;
    });
    Sums total;
    for (const Sums& cs : chunk_sums) total.add(cs);
    return total;
}

}  // namespace

namespace {

/// The intensity gradients of compute_intensity_gradients, each point's kk nearest given by
/// nearest(i, nn, sq) (nearest first, the point itself among them; returns the count).
template <class Nearest>
void gradients_from(RegCloud& cloud, std::size_t kk, const Nearest& nearest) {
    const std::size_t n = cloud.xyz.size();
    cloud.gradient.assign(n, Eigen::Vector3d::Zero());
    tbb::parallel_for(std::size_t{0}, (n + kChunk - 1) / kChunk, [&](std::size_t c) {
        std::uint32_t nn[kMaxGradientNeighbours];
        double sq[kMaxGradientNeighbours];
        const std::size_t end = std::min(n, (c + 1) * kChunk);
        for (std::size_t i = c * kChunk; i < end; ++i) {
            const Eigen::Vector3d& p = cloud.xyz[i];
            const Eigen::Vector3d& nrm = cloud.normals[i];
            const Eigen::Vector3d u = nrm.unitOrthogonal();
            const Eigen::Vector3d v = nrm.cross(u);
            const std::size_t found = nearest(i, kk, nn, sq);
            Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
            Eigen::Vector2d b = Eigen::Vector2d::Zero();
            std::size_t used = 0;
            for (std::size_t m = 0; m < found; ++m) {
                if (nn[m] == i) continue;
                const Eigen::Vector3d dp = cloud.xyz[nn[m]] - p;
                const Eigen::Vector2d row(u.dot(dp), v.dot(dp));
                const double di = double(cloud.intensity[nn[m]]) - cloud.intensity[i];
                a.noalias() += row * row.transpose();
                b += di * row;
                ++used;
            }
            if (used < 3) continue;
            a.diagonal().array() += 1e-12 + 1e-6 * a.trace();
            const Eigen::Vector2d x = a.ldlt().solve(b);
            if (x.allFinite()) cloud.gradient[i] = x(0) * u + x(1) * v;
        }
    });
}

}  // namespace

void compute_intensity_gradients(RegCloud& cloud, const KdTree& tree, int k) {
    if (!cloud.has_colour()) return;
    const std::size_t kk = std::min<std::size_t>(std::max(k, 4), kMaxGradientNeighbours);
    gradients_from(cloud, kk, [&](std::size_t i, std::size_t m, std::uint32_t* nn, double* sq) {
        return tree.knn(cloud.xyz[i], m, nn, sq);
    });
}

void compute_intensity_gradients(RegCloud& cloud, const KdTree& tree, int k,
                                 const std::vector<std::uint32_t>& neighbours) {
    if (!cloud.has_colour()) return;
    const std::size_t n = cloud.xyz.size();
    const std::size_t kk = std::min<std::size_t>(std::max(k, 4), kMaxGradientNeighbours);
    const std::size_t stride = n ? neighbours.size() / n : 0;
    if (stride < std::min(kk, n) || stride * n != neighbours.size())
        return compute_intensity_gradients(cloud, tree, k);
    gradients_from(cloud, kk, [&](std::size_t i, std::size_t m, std::uint32_t* nn, double*) {
        const std::size_t found = std::min(m, stride);
        std::copy_n(neighbours.begin() + i * stride, found, nn);
        return found;
    });
}

PairIcpOutcome pair_icp(const RegCloud& source, const RegCloud& target, const KdTree& target_tree,
                        const Pose& initial_target_from_source, const PairIcpSettings& settings,
                        double eval_distance) {
    PairIcpOutcome out;
    Pose pose = initial_target_from_source;
    std::vector<Sums> chunk_sums;
    std::vector<std::uint32_t> hint;  // each source point's last match
    double extent = 0.0;              // largest distance of a source point from its centroid
    for (const auto& p : source.xyz) extent = std::max(extent, (p - source.centroid).norm());
    const std::size_t stages = settings.distances.size();
    for (std::size_t st = 0; st < stages; ++st) {
        const double dmax = settings.distances[st];
        // Coarse stages only steer: every 2^k-th source point (k = stages left), at least
        // ~1000 points; the final stage uses all.
        std::size_t stride = settings.stride_coarse_stages
                                 ? std::size_t{1} << std::min<std::size_t>(stages - 1 - st, 3)
                                 : 1;
        while (stride > 1 && source.xyz.size() / stride < 1000) stride /= 2;
        const double used = static_cast<double>((source.xyz.size() + stride - 1) / stride);
        double prev_fitness = -1, prev_rmse = -1;
        const double min_motion = st + 1 < stages ? 5.0 * settings.min_motion : settings.min_motion;
        bool stage_converged = false;
        for (int it = 0; it < settings.max_iterations; ++it) {
            const Eigen::Vector3d centre = pose * source.centroid;
            const Sums s = accumulate(source, target, target_tree, pose, centre, dmax, settings,
                                      true, stride, hint, chunk_sums);
            if (settings.relative_fitness > 0 || settings.relative_rmse > 0) {
                const double fitness = double(s.matched) / used;
                const double rmse = s.matched ? std::sqrt(s.sq_dist / double(s.matched)) : 0.0;
                if (prev_fitness >= 0 &&
                    std::abs(fitness - prev_fitness) <=
                        settings.relative_fitness * std::max(fitness, 1e-300) &&
                    std::abs(rmse - prev_rmse) <= settings.relative_rmse * std::max(rmse, 1e-300)) {
                    stage_converged = true;
                    break;
                }
                prev_fitness = fitness;
                prev_rmse = rmse;
            }
            if (s.matched < 6) break;
            Mat6 h = s.h;
            h.diagonal().array() += 1e-9 * std::max(h.diagonal().maxCoeff(), 1e-300);
            Eigen::LDLT<Mat6> ldlt(h);
            if (ldlt.info() != Eigen::Success) break;
            const Vec6 x = ldlt.solve(-s.g);
            if (!x.allFinite()) break;
            pose = orthonormalized(rigid_update(x, centre) * pose);
            ++out.iterations;
            const bool small_step = settings.min_rotation_rad >= 0 &&
                                    x.head<3>().norm() <= settings.min_rotation_rad &&
                                    x.tail<3>().norm() <= settings.min_translation;
            if (x.head<3>().norm() * extent + x.tail<3>().norm() <= min_motion || small_step) {
                stage_converged = true;
                break;
            }
        }
        out.converged = stage_converged;
    }
    const Sums s = accumulate(source, target, target_tree, pose, pose * source.centroid,
                              eval_distance, settings, false, 1, hint, chunk_sums);
    out.target_from_source = pose;
    out.correspondences = s.matched;
    out.consistent = s.consistent;
    out.fitness = source.xyz.empty() ? 0.0 : double(s.matched) / double(source.xyz.size());
    out.inlier_rmse = s.matched ? std::sqrt(s.sq_dist / s.matched) : 0.0;
    out.plane_rmse = s.matched ? std::sqrt(s.sq_plane / s.matched) : 0.0;
    out.colour_rmse = s.matched ? std::sqrt(s.sq_colour / s.matched) : 0.0;
    out.information = s.info;
    return out;
}

}  // namespace rgbd::internal
