// FPFH features and RANSAC feature matching (see global_registration.hpp).
#include "algorithms/registration/global_registration.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>
#include <string>

#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/error.hpp"
#include "toolkit/random.hpp"

namespace rgbd::registration {

namespace {

constexpr std::size_t kChunk = 256;
constexpr int kBins = 11;

/// Rusu's angle triplet (and the distance) of a point pair, as Open3D ComputePairFeatures.
bool pair_features(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1, const Eigen::Vector3d& p2,
                   const Eigen::Vector3d& n2, double f[3]) {
    Eigen::Vector3d dp = p2 - p1;
    const double dist = dp.norm();
    if (dist == 0.0) return false;
    Eigen::Vector3d a = n1, b = n2;
    const double angle1 = n1.dot(dp) / dist;
    const double angle2 = n2.dot(dp) / dist;
    double f3;
    if (std::acos(std::abs(angle1)) > std::acos(std::abs(angle2))) {
        a = n2;
        b = n1;
        dp = -dp;
        f3 = -angle2;
    } else {
        f3 = angle1;
    }
    Eigen::Vector3d v = dp.cross(a);
    const double vn = v.norm();
    if (vn == 0.0) return false;
    v /= vn;
    const Eigen::Vector3d w = a.cross(v);
    f[0] = std::atan2(w.dot(b), a.dot(b));  // alpha in [-pi, pi]
    f[1] = v.dot(b);                        // phi in [-1, 1]
    f[2] = f3;                              // theta in [-1, 1]
    return true;
}

int bin_of(double value, double lo, double hi) {
    const int b = static_cast<int>(std::floor(kBins * (value - lo) / (hi - lo)));
    return std::clamp(b, 0, kBins - 1);
}

/// kd-tree over FPFH descriptors (L2 in 33 dimensions).
class FeatureTree {
public:
    explicit FeatureTree(const std::vector<Fpfh>& f)
        : adaptor_{&f}, index_(33, adaptor_, nanoflann::KDTreeSingleIndexAdaptorParams(15)) {
        if (!f.empty()) index_.buildIndex();
    }
    std::uint32_t nearest(const Fpfh& q) const {
        std::uint32_t idx = 0;
        float d2 = 0;
        nanoflann::KNNResultSet<float, std::uint32_t> rs(1);
        rs.init(&idx, &d2);
        index_.findNeighbors(rs, q.data(), nanoflann::SearchParams());
        return idx;
    }

private:
    using Adaptor = internal::VectorAdaptor<Fpfh, float>;
    using Index = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Adaptor>,
                                                      Adaptor, 33, std::uint32_t>;
    Adaptor adaptor_;
    Index index_;
};

Pose fit_rigid(const Eigen::Matrix3Xd& src, const Eigen::Matrix3Xd& dst) {
    Pose pose = Pose::Identity();
    pose.matrix() = Eigen::umeyama(src, dst, false);
    return pose;
}

}  // namespace

std::vector<Fpfh> compute_fpfh(const std::vector<Eigen::Vector3d>& xyz,
                               const std::vector<Eigen::Vector3d>& normals, double radius,
                               int max_neighbours) {
    RGBD_CHECK(xyz.size() == normals.size(), "fpfh: points and normals differ in number");
    RGBD_CHECK(std::isfinite(radius) && radius > 0, "fpfh: radius must be positive");
    RGBD_CHECK(max_neighbours >= 3, "fpfh: max_neighbours must be at least 3");
    const std::size_t n = xyz.size();
    const internal::KdTree tree(xyz);
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    // Neighbour lists (self first), capped at max_neighbours nearest within radius.
    std::vector<std::vector<std::pair<std::uint32_t, double>>> nbrs(n);
    std::vector<Fpfh> spfh(n, Fpfh::Zero());
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
        const std::size_t end = std::min(n, (c + 1) * kChunk);
        for (std::size_t i = c * kChunk; i < end; ++i) {
            auto& nb = nbrs[i];
            tree.radius(xyz[i], radius, nb);
            if (nb.size() > static_cast<std::size_t>(max_neighbours)) nb.resize(max_neighbours);
            if (nb.size() < 2) continue;
            const float incr = 100.0f / static_cast<float>(nb.size() - 1);
            double f[3];
            for (const auto& [j, d2] : nb) {
                if (j == i || !pair_features(xyz[i], normals[i], xyz[j], normals[j], f)) continue;
                spfh[i][bin_of(f[0], -M_PI, M_PI)] += incr;
                spfh[i][kBins + bin_of(f[1], -1.0, 1.0)] += incr;
                spfh[i][2 * kBins + bin_of(f[2], -1.0, 1.0)] += incr;
            }
        }
    });
    std::vector<Fpfh> out(n, Fpfh::Zero());
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
        const std::size_t end = std::min(n, (c + 1) * kChunk);
        for (std::size_t i = c * kChunk; i < end; ++i) {
            if (nbrs[i].size() < 2) continue;
            Fpfh acc = Fpfh::Zero();
            float sum[3] = {0, 0, 0};
            for (const auto& [j, d2] : nbrs[i]) {
                if (j == i || d2 <= 0) continue;
                const float inv = 1.0f / static_cast<float>(std::sqrt(d2));
                for (int b = 0; b < 33; ++b) {
                    const float val = spfh[j][b] * inv;
                    sum[b / kBins] += val;
                    acc[b] += val;
                }
            }
            for (float& s : sum) s = s != 0 ? 100.0f / s : 0.0f;
            for (int b = 0; b < 33; ++b) out[i][b] = acc[b] * sum[b / kBins] + spfh[i][b];
        }
    });
    return out;
}

void RansacOptions::check() const {
    check_range("ransac: iterations", iterations, Range::closed(1, 100000000));
    RGBD_CHECK(std::isfinite(inlier_distance) && inlier_distance > 0,
               "ransac: inlier_distance must be positive");
    check_range("ransac: edge_ratio", edge_ratio, Range::open_closed(0, 1));
    RGBD_CHECK(max_prior_rotation_deg > 0, "ransac: max_prior_rotation_deg must be positive");
    RGBD_CHECK(!prior || prior->matrix().allFinite(), "ransac: prior pose is not finite");
}

RansacResult ransac_feature_match(const std::vector<Eigen::Vector3d>& source_xyz,
                                  const std::vector<Fpfh>& source_features,
                                  const std::vector<Eigen::Vector3d>& target_xyz,
                                  const std::vector<Fpfh>& target_features,
                                  const RansacOptions& options) {
    options.check();
    RGBD_CHECK(
        source_xyz.size() == source_features.size() && target_xyz.size() == target_features.size(),
        "ransac: points and features differ in number");
    RansacResult result;
    if (source_xyz.size() < 3 || target_xyz.size() < 3) return result;

    // Nearest-feature correspondences (mutual when asked).
    const FeatureTree ttree(target_features);
    std::vector<std::uint32_t> fwd(source_xyz.size());
    tbb::parallel_for(std::size_t{0}, source_xyz.size(),
                      [&](std::size_t i) { fwd[i] = ttree.nearest(source_features[i]); });
    std::vector<std::pair<std::uint32_t, std::uint32_t>> corr;
    if (options.mutual) {
        const FeatureTree stree(source_features);
        std::vector<std::uint32_t> back(target_xyz.size());
        tbb::parallel_for(std::size_t{0}, target_xyz.size(),
                          [&](std::size_t j) { back[j] = stree.nearest(target_features[j]); });
        for (std::uint32_t i = 0; i < fwd.size(); ++i)
            if (back[fwd[i]] == i) corr.emplace_back(i, fwd[i]);
        if (corr.size() < 30)  // too few mutual matches: fall back to one-way
            corr.clear();
    }
    if (corr.empty())
        for (std::uint32_t i = 0; i < fwd.size(); ++i) corr.emplace_back(i, fwd[i]);
    result.correspondences = corr.size();
    const std::size_t nc = corr.size();
    if (nc < 3) return result;

    const double inlier_sq = options.inlier_distance * options.inlier_distance;
    const double cos_prior = std::cos(options.max_prior_rotation_deg * M_PI / 180.0);
    auto count_inliers = [&](const Pose& pose) {
        std::size_t c = 0;
        for (const auto& [s, t] : corr)
            if ((pose * source_xyz[s] - target_xyz[t]).squaredNorm() <= inlier_sq) ++c;
        return c;
    };

    constexpr int kBlock = 512;
    const int blocks = (options.iterations + kBlock - 1) / kBlock;
    struct Best {
        std::size_t inliers = 0;
        long long iteration = -1;
        Pose pose = Pose::Identity();
    };
    std::vector<Best> block_best(blocks);
    tbb::parallel_for(0, blocks, [&](int b) {
        Best best;
        Eigen::Matrix3d sm, tm;
        const int end = std::min(options.iterations, (b + 1) * kBlock);
        for (int it = b * kBlock; it < end; ++it) {
            std::uint64_t state = splitmix64(options.seed * 0x100000001b3ULL + std::uint64_t(it));
            std::size_t pick[3];
            for (int k = 0; k < 3; ++k) {
                state = splitmix64(state);
                pick[k] = state % nc;
            }
            if (pick[0] == pick[1] || pick[0] == pick[2] || pick[1] == pick[2]) continue;
            for (int k = 0; k < 3; ++k) {
                sm.col(k) = source_xyz[corr[pick[k]].first];
                tm.col(k) = target_xyz[corr[pick[k]].second];
            }
            bool ok = true;
            for (int a = 0; a < 3 && ok; ++a)
                for (int c = a + 1; c < 3 && ok; ++c) {
                    const double ds = (sm.col(a) - sm.col(c)).norm();
                    const double dt = (tm.col(a) - tm.col(c)).norm();
                    ok = ds >= options.edge_ratio * dt && dt >= options.edge_ratio * ds &&
                         ds > options.inlier_distance;
                }
            if (!ok) continue;
            const Pose pose = fit_rigid(sm, tm);
            if (!pose.matrix().allFinite()) continue;
            if ((pose * sm - tm).colwise().squaredNorm().maxCoeff() > inlier_sq) continue;
            if (options.prior) {
                const Eigen::Matrix3d d = pose.linear() * options.prior->linear().transpose();
                if ((d.trace() - 1.0) / 2.0 < cos_prior) continue;
            }
            const std::size_t c = count_inliers(pose);
            if (c > best.inliers) best = Best{c, it, pose};
        }
        block_best[b] = best;
    });
    Best best;
    for (const Best& b : block_best)
        if (b.inliers > best.inliers) best = b;  // blocks in order: lowest iteration wins ties
    if (best.inliers < 3) return result;

    // Refit to the inliers (twice: the refit can admit a few more).
    Pose pose = best.pose;
    for (int round = 0; round < 2; ++round) {
        std::vector<std::size_t> in;
        for (std::size_t k = 0; k < nc; ++k)
            if ((pose * source_xyz[corr[k].first] - target_xyz[corr[k].second]).squaredNorm() <=
                inlier_sq)
                in.push_back(k);
        if (in.size() < 3) break;
        Eigen::Matrix3Xd s(3, in.size()), t(3, in.size());
        for (std::size_t k = 0; k < in.size(); ++k) {
            s.col(k) = source_xyz[corr[in[k]].first];
            t.col(k) = target_xyz[corr[in[k]].second];
        }
        const Pose refit = fit_rigid(s, t);
        if (!refit.matrix().allFinite()) break;
        if (count_inliers(refit) < count_inliers(pose)) break;
        pose = refit;
    }
    result.target_from_source = orthonormalized(pose);
    result.inliers = count_inliers(result.target_from_source);
    result.found = true;
    return result;
}

}  // namespace rgbd::registration
