#include "algorithms/segment/ground_plane.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "algorithms/internal/plane_fit.hpp"
#include "toolkit/order_statistics.hpp"
#include "toolkit/random.hpp"

namespace rgbd::segment::detail {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// A view's refit of a wall stays within this of the pooled plane's normal, degrees: the cone
/// of its RANSAC. The refit absorbs the calibration error between views (about a degree); a
/// side wall is seen at grazing incidence, where a least-squares fit tilts towards the rays
/// (the APC shelf's second side wall seen at 75 degrees: 9-16 degrees), and a tilted plane cuts
/// a wedge off what stands in front of the wall. Such a view keeps the RANSAC's plane. (The
/// ground's refit keeps ground_max_tilt_deg: its least-squares tilt is what tells the curved
/// top of a ball from a floor.)
constexpr double kRefitConeDeg = 5.0;

/// internal::fit_plane into a Plane.
bool fit_plane(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& up, Plane& out,
               double* rms = nullptr) {
    return internal::fit_plane(points, up, out.n, out.d, rms);
}

/// The half-sample mode of `values` (Bickel and Fruehwirth, "On a fast, robust estimator of
/// the mode", 2006): the shortest interval holding half of the values, repeatedly, until two or
/// three are left. Robust to anything under half of the values, on either side. Sorts `values`.
double half_sample_mode(std::vector<double>& values) {
    std::sort(values.begin(), values.end());
    std::size_t lo = 0, n = values.size();
    while (n > 3) {
        const std::size_t half = (n + 1) / 2;
        std::size_t best = lo;
        for (std::size_t i = lo; i + half <= lo + n; ++i)
            if (values[i + half - 1] - values[i] < values[best + half - 1] - values[best]) best = i;
        lo = best, n = half;
    }
    if (n == 3)
        return values[lo + 1] - values[lo] < values[lo + 2] - values[lo + 1]
                   ? 0.5 * (values[lo] + values[lo + 1])
                   : (values[lo + 1] - values[lo] > values[lo + 2] - values[lo + 1]
                          ? 0.5 * (values[lo + 1] + values[lo + 2])
                          : values[lo + 1]);
    return n == 2 ? 0.5 * (values[lo] + values[lo + 1]) : values[lo];
}

/// Moves `plane` along its normal onto the surface it was fitted to: to the half-sample mode of
/// the heights of the points of `facing` within `band` of it. What stands on or against the
/// surface (under half of the points) then does not pull the plane off it.
void centre_on_surface(const std::vector<Eigen::Vector3d>& facing, double band, Plane& plane) {
    // At most about 16,384 heights (every k-th point): the mode of a plane seen by a sensor
    // holds tens of thousands, and the sort is the cost.
    const std::size_t stride = facing.size() / 16384 + 1;
    std::vector<double> heights;
    heights.reserve(facing.size() / stride + 1);
    for (std::size_t i = 0; i < facing.size(); i += stride) {
        const double h = plane.height(facing[i]);
        if (std::abs(h) <= band) heights.push_back(h);
    }
    if (heights.size() < 50) return;
    plane.d -= half_sample_mode(heights);
}

/// A height's distance from a plane: in metres and in units of the sensor's sigma_z.
struct Deviation {
    double metres = 0;
    double sigmas = 0;
};

/// The robust deviation (1.4826 x the median |height|) in metres and in units of sigma_z.
Deviation robust_deviation(const std::vector<Deviation>& d) {
    std::vector<double> m(d.size()), s(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) m[i] = d[i].metres, s[i] = d[i].sigmas;
    return {1.4826 * rank_quantile(m, 0.5), 1.4826 * rank_quantile(s, 0.5)};
}

/// The surface facing the plane: the points within half a band of `fit.plane` whose grid
/// normal lies within ground_max_tilt_deg of it (all of them without normals). Least squares on
/// them (a plane that tilts more than that from `fit.plane` ends the fit), then on those within
/// 3 robust deviations (at least 5 mm); fit.robust_m and fit.normalized: their robust deviation
/// (1.4826 x the median |height|) in metres and in units of the sensor's sigma_z at each point's
/// depth and incidence (the surface's flatness), and fit.rms_m the same. A `wall` differs:
/// a least-squares plane out of the cone keeps the previous orientation; each round moves the
/// plane along its normal to the mode of the heights (centre_on_surface), so that what stands
/// against the wall does not pull it forward (the APC shelf's joke book, 1-2 cm in front of a
/// side wall); and fit.rms_m, the noise the cut allows for, is the lesser of the robust
/// deviation and the one of the points behind the plane, where nothing stands (the joke book:
/// 8-13 mm two-sided in the views that see the wall at 60-75 degrees, 1-3 mm behind), the next
/// round's band 3 of these. The plane and these figures become this fit's when it holds 50
/// points; `on_plane` receives the points of that fit.
void measure_flatness(const std::vector<Eigen::Vector3d>& xyz,
                      const std::vector<Eigen::Vector3d>& normals, denoise::NoiseModel model,
                      const SubjectOptions& o, bool wall, ViewGroundFit& fit,
                      std::vector<Eigen::Vector3d>& on_plane) {
    const double cos_tilt = std::cos(o.ground_max_tilt_deg * kDeg);
    std::vector<Eigen::Vector3d> facing;
    for (std::size_t i = 0; i < xyz.size(); ++i)
        if (std::abs(fit.plane.height(xyz[i])) <= 0.5 * o.ground_band_m && xyz[i].z() > 0 &&
            (normals.empty() || normals[i].dot(fit.plane.n) >= cos_tilt))
            facing.push_back(xyz[i]);
    Plane plane = fit.plane;
    double band = 0.5 * o.ground_band_m;
    std::vector<Deviation> both, behind;
    Deviation spread, least;
    std::vector<Eigen::Vector3d> in;
    for (int round = 0; round < 2; ++round) {
        in.clear();
        for (const auto& q : facing)
            if (std::abs(plane.height(q)) <= band) in.push_back(q);
        Plane refined;
        if (in.size() < 50 || !fit_plane(in, fit.plane.n, refined)) return;
        if (refined.n.dot(fit.plane.n) >= cos_tilt)
            plane = refined;
        else if (!wall)
            return;
        // A wall out of the cone keeps its orientation; its offset is the surface's mode.
        if (wall) centre_on_surface(facing, band, plane);
        both.clear(), behind.clear();
        for (const auto& q : in) {
            const double h = plane.height(q);
            const double cos_theta = std::clamp(std::abs(q.normalized().dot(plane.n)), 0.0, 1.0);
            const double theta = std::min(std::acos(cos_theta), 80.0 * kDeg);
            const Deviation d{std::abs(h), std::abs(h) / denoise::sigma_z_m(model, q.z(), theta)};
            both.push_back(d);
            if (h < 0) behind.push_back(d);
        }
        spread = robust_deviation(both);
        least = spread;
        if (wall && behind.size() >= 25) {
            const Deviation back = robust_deviation(behind);
            least = {std::min(spread.metres, back.metres), std::min(spread.sigmas, back.sigmas)};
        }
        band = std::max(3.0 * least.metres, 0.005);
    }
    fit.plane = plane;
    fit.facing = both.size();
    fit.robust_m = spread.metres;
    fit.normalized = spread.sigmas;
    fit.rms_m = least.metres;
    on_plane = std::move(in);
}

/// The points of `xyz` more than `half` behind `plane` (sensor frame) whose ray from the sensor
/// crosses the plane inside the convex hull of `on_plane` (the surface seen on it).
std::size_t seen_through(const std::vector<Eigen::Vector3d>& xyz, const Plane& plane,
                         const std::vector<Eigen::Vector3d>& on_plane, double half) {
    if (on_plane.size() < 3 || plane.d <= 0) return 0;
    const Eigen::Vector3d u = plane.n.unitOrthogonal(), v = plane.n.cross(u);
    std::vector<cv::Point2f> pts, hull;
    pts.reserve(on_plane.size());
    for (const auto& q : on_plane) pts.emplace_back(float(q.dot(u)), float(q.dot(v)));
    cv::convexHull(pts, hull);
    if (hull.size() < 3) return 0;
    std::size_t count = 0;
    for (const auto& q : xyz) {
        const double h = plane.height(q);
        if (h >= -half) continue;
        const Eigen::Vector3d c = (-plane.d / plane.n.dot(q)) * q;
        count +=
            cv::pointPolygonTest(hull, cv::Point2f(float(c.dot(u)), float(c.dot(v))), false) >= 0;
    }
    return count;
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
                                std::uint64_t seed, bool wall) {
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
        if (ransac_plane(near, pooled.n, std::cos(kRefitConeDeg * kDeg), 0.2 * o.ground_band_m,
                         std::max(50, o.iterations / 4), seed, local, score)) {
            // Two least-squares rounds: on the points within half a band of the RANSAC plane,
            // then on those within 3 RMS of that fit; a round whose plane leaves the RANSAC's
            // cone is not taken (the RANSAC plane or the first round stays).
            std::vector<Eigen::Vector3d> in;
            for (const auto& q : near)
                if (std::abs(local.height(q)) <= half) in.push_back(q);
            const double cos_cone = std::cos((wall ? kRefitConeDeg : o.ground_max_tilt_deg) * kDeg);
            Plane first;
            double r = 0;
            if (in.size() >= 50 && fit_plane(in, pooled.n, first, &r)) {
                if (wall) {  // a wall keeps the RANSAC plane when the least squares leave it
                    fit.plane = local;
                    fit.rms_m = r;
                }
                if (first.n.dot(pooled.n) > cos_cone) {
                    if (wall) fit.plane = first;
                    std::vector<Eigen::Vector3d> tight;
                    for (const auto& q : in)
                        if (std::abs(first.height(q)) <= std::max(3.0 * r, 0.005))
                            tight.push_back(q);
                    Plane second;
                    if (fit_plane(tight, pooled.n, second, &r) &&
                        (!wall || second.n.dot(pooled.n) > cos_cone)) {
                        fit.plane = second;
                        fit.rms_m = r;
                    }
                }
            }
        }
    }
    std::vector<Eigen::Vector3d> on_plane;
    if (fit.rms_m > 0) measure_flatness(xyz, normals, model, o, wall, fit, on_plane);
    if (wall) fit.through = seen_through(xyz, fit.plane, on_plane, half);
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
