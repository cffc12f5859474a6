#include "algorithms/segment/ground_plane.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "algorithms/internal/plane_fit.hpp"
#include "toolkit/order_statistics.hpp"
#include "toolkit/random.hpp"

namespace rgbd::segment::detail {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// internal::fit_plane into a Plane.
bool fit_plane(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& up, Plane& out,
               double* rms = nullptr) {
    return internal::fit_plane(points, up, out.n, out.d, rms);
}

/// The surface facing the plane: the points within half a band of `fit.plane` whose grid
/// normal lies within ground_max_tilt_deg of it (all of them without normals). Least squares on
/// them, then on those within 3 robust deviations (at least 5 mm); their robust deviation
/// (1.4826 x the median |height|) in metres and in units of the sensor's sigma_z at each point's
/// depth and incidence. The plane and fit.rms_m become this fit's when it holds 50 points.
void measure_flatness(const std::vector<Eigen::Vector3d>& xyz,
                      const std::vector<Eigen::Vector3d>& normals, denoise::NoiseModel model,
                      const SubjectOptions& o, ViewGroundFit& fit) {
    const double cos_tilt = std::cos(o.ground_max_tilt_deg * kDeg);
    std::vector<Eigen::Vector3d> facing;
    for (std::size_t i = 0; i < xyz.size(); ++i)
        if (std::abs(fit.plane.height(xyz[i])) <= 0.5 * o.ground_band_m && xyz[i].z() > 0 &&
            (normals.empty() || normals[i].dot(fit.plane.n) >= cos_tilt))
            facing.push_back(xyz[i]);
    Plane plane = fit.plane;
    double band = 0.5 * o.ground_band_m;
    std::vector<double> abs_h, norm_h;
    for (int round = 0; round < 2; ++round) {
        std::vector<Eigen::Vector3d> in;
        for (const auto& q : facing)
            if (std::abs(plane.height(q)) <= band) in.push_back(q);
        Plane refined;
        if (in.size() < 50 || !fit_plane(in, fit.plane.n, refined) ||
            refined.n.dot(fit.plane.n) < cos_tilt)
            return;
        plane = refined;
        abs_h.clear(), norm_h.clear();
        for (const auto& q : in) {
            const double h = std::abs(plane.height(q));
            const double cos_theta = std::clamp(std::abs(q.normalized().dot(plane.n)), 0.0, 1.0);
            const double theta = std::min(std::acos(cos_theta), 80.0 * kDeg);
            abs_h.push_back(h);
            norm_h.push_back(h / denoise::sigma_z_m(model, q.z(), theta));
        }
        band = std::max(3.0 * 1.4826 * rank_quantile(abs_h, 0.5), 0.005);
    }
    fit.plane = plane;
    fit.facing = abs_h.size();
    fit.robust_m = 1.4826 * rank_quantile(abs_h, 0.5);
    fit.normalized = 1.4826 * rank_quantile(norm_h, 0.5);
    fit.rms_m = fit.robust_m;
}

/// Whether a sample at p with normal n votes for `plane`: within `band` of it and facing it.
inline bool votes_for(const Plane& plane, const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                      double band, double cos_tilt) {
    return std::abs(plane.height(p)) <= band && std::abs(n.dot(plane.n)) >= cos_tilt;
}

}  // namespace

bool ransac_plane(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& up,
                  double cos_tilt, double inlier, int iterations, std::uint64_t seed, Plane& best,
                  std::size_t& best_score) {
    best_score =
        internal::ransac_plane(points, up, cos_tilt, inlier, iterations, seed, best.n, best.d);
    return best_score >= 3;
}

std::optional<Plane> pooled_ground(const std::vector<GroundSample>& all_samples,
                                   const Eigen::Vector3d& up, const SubjectOptions& o,
                                   std::size_t& inliers) {
    inliers = 0;
    if (all_samples.size() < 100) return std::nullopt;
    const double cos_tilt = std::cos(o.ground_max_tilt_deg * kDeg);
    std::vector<Eigen::Vector3d> facing;
    for (const auto& s : all_samples)
        if (s.n.isZero() || s.n.dot(up) >= cos_tilt) facing.push_back(s.p);  // zero: unknown
    const double n_all = static_cast<double>(all_samples.size());
    if (facing.size() < o.ground_min_share * n_all) return std::nullopt;
    const double inlier = 0.5 * o.ground_band_m;
    Plane best;
    std::size_t best_score = 0;
    if (!ransac_plane(facing, up, cos_tilt, inlier, o.iterations, o.seed, best, best_score))
        return std::nullopt;
    // A large plane lower down is the ground, not this one.
    std::vector<Eigen::Vector3d> lower;
    for (const auto& q : facing)
        if (best.height(q) < -2.0 * o.ground_band_m) lower.push_back(q);
    Plane low;
    std::size_t low_score = 0;
    if (ransac_plane(lower, up, cos_tilt, inlier, o.iterations, o.seed + 1, low, low_score) &&
        low_score * 3 >= best_score && low_score >= o.ground_min_share * n_all)
        best = low;
    for (const double band : {inlier, 0.5 * inlier, 0.25 * inlier}) {
        std::vector<Eigen::Vector3d> in;
        for (const auto& q : facing)
            if (std::abs(best.height(q)) <= band) in.push_back(q);
        Plane refined;
        if (!fit_plane(in, up, refined) || refined.n.dot(up) < cos_tilt) break;
        best = refined;
    }
    for (const auto& q : facing) inliers += std::abs(best.height(q)) <= inlier;
    if (inliers < o.ground_min_share * n_all) return std::nullopt;
    return best;
}

std::optional<Plane> pooled_bounding_plane(const std::vector<GroundSample>& samples,
                                           std::vector<std::uint8_t>& used,
                                           const Eigen::Vector3d& cameras, const SubjectOptions& o,
                                           std::uint64_t seed, std::size_t& inliers,
                                           std::size_t& behind) {
    inliers = behind = 0;
    // The samples with a grid normal vote for a plane when they lie within half a band of it
    // and face it (within ground_max_tilt_deg): one surface, not a slice through several.
    std::vector<std::size_t> open;
    for (std::size_t i = 0; i < samples.size(); ++i)
        if (!used[i] && !samples[i].n.isZero()) open.push_back(i);
    const double n_all = static_cast<double>(samples.size());
    if (open.size() < 100 || open.size() < o.ground_min_share * n_all) return std::nullopt;
    const double inlier = 0.5 * o.ground_band_m;
    const double cos_tilt = std::cos(o.ground_max_tilt_deg * kDeg);
    // The open samples by coordinate (structure of arrays): the hypotheses' scoring loop,
    // 500 planes x up to 80000 samples, then compiles to vector instructions. The same
    // operations in the same order as Plane::height and Eigen's dot, so the same votes.
    const std::size_t m = open.size();
    std::vector<double> soa(6 * m);
    double *px = soa.data(), *py = px + m, *pz = py + m, *nx = pz + m, *ny = nx + m, *nz = ny + m;
    for (std::size_t j = 0; j < m; ++j) {
        const GroundSample& s = samples[open[j]];
        px[j] = s.p.x(), py[j] = s.p.y(), pz[j] = s.p.z();
        nx[j] = s.n.x(), ny[j] = s.n.y(), nz[j] = s.n.z();
    }
    internal::PlaneVoteInput soa_in;
    soa_in.px = px, soa_in.py = py, soa_in.pz = pz, soa_in.m = m;
    soa_in.nx = nx, soa_in.ny = ny, soa_in.nz = nz;
    auto count_votes = [&](const Plane& p, double band) {
        return internal::count_plane_votes(soa_in, p.n, p.d, band, cos_tilt);
    };
    auto votes = [&](const Plane& p, double band, std::vector<Eigen::Vector3d>* in) {
        if (!in) return count_votes(p, band);
        std::size_t count = 0;
        for (const std::size_t i : open)
            if (votes_for(p, samples[i].p, samples[i].n, band, cos_tilt)) {
                ++count;
                in->push_back(samples[i].p);
            }
        return count;
    };
    // The hypotheses are drawn in sequence (the seed's stream), scored in parallel, and the
    // first of the highest score wins: the choice of a sequential loop.
    std::vector<Plane> hypotheses;
    std::uint64_t state = seed;
    for (int it = 0; it < o.iterations; ++it) {
        const Eigen::Vector3d& a = samples[open[splitmix64_next(state) % open.size()]].p;
        const Eigen::Vector3d& b = samples[open[splitmix64_next(state) % open.size()]].p;
        const Eigen::Vector3d& c = samples[open[splitmix64_next(state) % open.size()]].p;
        Eigen::Vector3d n = (b - a).cross(c - a);
        if (n.norm() < 1e-12) continue;
        hypotheses.push_back({n.normalized(), -n.normalized().dot(a)});
    }
    std::vector<std::size_t> counts(hypotheses.size());
    tbb::parallel_for(std::size_t(0), hypotheses.size(),
                      [&](std::size_t h) { counts[h] = votes(hypotheses[h], inlier, nullptr); });
    Plane best;
    std::size_t score = 0;
    for (std::size_t h = 0; h < hypotheses.size(); ++h)
        if (counts[h] > score) score = counts[h], best = hypotheses[h];
    if (score < 3) return std::nullopt;
    for (const double band : {inlier, 0.5 * inlier, 0.25 * inlier}) {
        std::vector<Eigen::Vector3d> in;
        votes(best, band, &in);
        Plane refined;
        if (!fit_plane(in, best.n, refined)) break;
        best = refined;
    }
    if (best.height(cameras) < 0) best.n = -best.n, best.d = -best.d;
    for (std::size_t i = 0; i < samples.size(); ++i) {
        const double h = best.height(samples[i].p);
        behind += h < -o.ground_band_m;
        if (!used[i] && std::abs(h) <= inlier &&
            (samples[i].n.isZero() || std::abs(samples[i].n.dot(best.n)) >= cos_tilt))
            ++inliers, used[i] = 1;
    }
    if (inliers < o.ground_min_share * n_all) return std::nullopt;
    return best;
}

ViewGroundFit refit_view_ground(const std::vector<Eigen::Vector3d>& xyz, const Plane& pooled,
                                const std::vector<Eigen::Vector3d>& normals,
                                denoise::NoiseModel model, const SubjectOptions& o,
                                std::uint64_t seed) {
    ViewGroundFit fit;
    fit.plane = pooled;
    fit.points = xyz.size();
    const double half = 0.5 * o.ground_band_m;
    std::vector<Eigen::Vector3d> near;
    for (const auto& q : xyz)
        if (std::abs(pooled.height(q)) <= o.ground_band_m) near.push_back(q);
    if (near.size() >= 50) {
        Plane local;
        std::size_t score = 0;
        if (ransac_plane(near, pooled.n, std::cos(5.0 * kDeg), 0.2 * o.ground_band_m,
                         std::max(50, o.iterations / 4), seed, local, score)) {
            // Two least-squares rounds: on the points within half a band of the RANSAC plane,
            // then on those within 3 RMS of that fit.
            std::vector<Eigen::Vector3d> in;
            for (const auto& q : near)
                if (std::abs(local.height(q)) <= half) in.push_back(q);
            Plane first;
            double r = 0;
            if (in.size() >= 50 && fit_plane(in, pooled.n, first, &r) &&
                first.n.dot(pooled.n) > std::cos(o.ground_max_tilt_deg * kDeg)) {
                std::vector<Eigen::Vector3d> tight;
                for (const auto& q : in)
                    if (std::abs(first.height(q)) <= std::max(3.0 * r, 0.005)) tight.push_back(q);
                Plane second;
                if (fit_plane(tight, pooled.n, second, &r)) {
                    fit.plane = second;
                    fit.rms_m = r;
                }
            }
        }
    }
    if (fit.rms_m > 0) measure_flatness(xyz, normals, model, o, fit);
    for (const auto& q : xyz) {
        const double h = fit.plane.height(q);
        fit.below += h < -half;
        fit.above += h > half;
    }
    return fit;
}

GroundCut cut_above_ground(const std::vector<Eigen::Vector3d>& xyz, const ViewGroundFit& fit,
                           denoise::NoiseModel model, const SubjectOptions& o,
                           std::vector<std::uint8_t>& removed) {
    GroundCut result;
    std::vector<double> margins;
    for (std::size_t i = 0; i < xyz.size(); ++i) {
        const Eigen::Vector3d& q = xyz[i];
        const double cos_theta = std::clamp(std::abs(q.normalized().dot(fit.plane.n)), 0.0, 1.0);
        const double theta = std::min(std::acos(cos_theta), 80.0 * kDeg);
        const double margin =
            std::max(o.ground_min_margin_m,
                     o.ground_sigmas * denoise::sigma_z_m(model, q.z(), theta) + fit.rms_m);
        const double h = fit.plane.height(q);
        if (h < margin) {
            result.cut += removed[i] == 0;
            removed[i] = 1;
            if (h > -margin) margins.push_back(margin);
        }
    }
    result.margin_m = margins.empty() ? o.ground_min_margin_m : rank_quantile(margins, 0.5);
    return result;
}

}  // namespace rgbd::segment::detail
