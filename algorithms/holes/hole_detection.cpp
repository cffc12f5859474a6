#include "algorithms/holes/hole_detection.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <numeric>
#include <optional>
#include <string>

#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/neighbour_lists.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

namespace {

constexpr std::uint32_t kNone = UINT32_MAX;

void check_points(const SurfacePoints& points) {
    RGBD_CHECK(points.size() >= 4,
               "holes: need at least 4 points, got " + std::to_string(points.size()));
    for (const auto& p : points.position)
        RGBD_CHECK(p.allFinite(), "holes: a point has a non-finite coordinate");
    RGBD_CHECK(points.normal.empty() || points.normal.size() == points.size(),
               "holes: normal count differs from point count");
    RGBD_CHECK(points.color.empty() || points.color.size() == points.size(),
               "holes: colour count differs from point count");
    RGBD_CHECK(points.view.empty() || points.view.size() == points.size(),
               "holes: view count differs from point count");
}

/// Any unit vector orthogonal to n, chosen consistently.
Eigen::Vector3d orthogonal(const Eigen::Vector3d& n) {
    const Eigen::Vector3d axis =
        std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    return n.cross(axis).normalized();
}

constexpr EnumName<HoleKind> kHoleKindNames[] = {{HoleKind::kUnknown, "unknown"},
                                                 {HoleKind::kOcclusion, "occlusion"},
                                                 {HoleKind::kOpening, "opening"}};

}  // namespace

const char* to_string(HoleKind kind) { return name_of(kHoleKindNames, kind, "unknown"); }

void NeighbourhoodOptions::check() const {
    check_range("holes: k", k, Range::closed(3, 256));
    check_range("holes: radius factor", radius_factor, Range::closed(0.0, 50.0));
    RGBD_CHECK(max_neighbours >= k && max_neighbours <= 1024,
               "holes: max_neighbours must be in [k, 1024]");
}

void GradientOptions::check() const { neighbourhood.check(); }

void BoundaryOptions::check() const {
    neighbourhood.check();
    RGBD_CHECK(std::isfinite(spacing_m) && spacing_m >= 0.0, "holes: spacing must be >= 0");
    RGBD_CHECK(std::isfinite(w_angle) && std::isfinite(w_halfdisk) && std::isfinite(w_shape) &&
                   w_angle >= 0 && w_halfdisk >= 0 && w_shape >= 0 &&
                   w_angle + w_halfdisk + w_shape > 0,
               "holes: criterion weights must be >= 0 and not all 0");
    check_range("holes: threshold", threshold, Range::open_closed(0.0, 1.0));
    RGBD_CHECK(std::isfinite(lambda_b0) && std::isfinite(lambda_b1) && lambda_b0 >= lambda_b1 &&
                   lambda_b1 >= 0 && lambda_b0 + lambda_b1 <= 1.0 + 1e-9,
               "holes: lambda_b must be ordered and sum to at most 1");
    check_range("holes: coherence passes", coherence_passes, Range::closed(0, 100));
    check_range("holes: min loop points", min_loop_points, Range::closed(1, 100000));
    check_range("holes: small-hole diameter", small_max_diameter, Range::open_closed(0, 1e4),
                "spacings");
    RGBD_CHECK(small_max_points >= 1, "holes: small-hole point limit must be >= 1, got " +
                                          std::to_string(small_max_points));
    RGBD_CHECK(std::isfinite(hysteresis_threshold) && hysteresis_threshold >= 0 &&
                   hysteresis_threshold <= threshold,
               "holes: hysteresis threshold must be in [0, threshold]");
    check_range("holes: hysteresis rings", hysteresis_rings, Range::closed(0, 100));
    check_range("holes: link distance", link_distance, Range::open_closed(0, 20), "spacings");
    check_visibility("holes", visible_max_angle_deg, ray_clearance);
}

void check_visibility(const char* who, double max_angle_deg, double ray_clearance) {
    check_range(std::string(who) + ": visibility angle", max_angle_deg, Range::open(0, 90),
                "degrees");
    check_range(std::string(who) + ": ray clearance", ray_clearance, Range::open_closed(0, 20),
                "spacings");
}

namespace {

/// compute_surface_gradient over a given neighbourhood graph.
SurfaceGradient gradient_over(const SurfacePoints& points, const Neighbourhood& graph,
                              const std::vector<SensorView>& sensors,
                              const GradientOptions& options) {
    const std::size_t n = points.size();
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : points.position) centroid += p;
    centroid /= static_cast<double>(n);
    const bool given = !points.normal.empty() && !options.recompute_normals;
    SurfaceGradient g;
    g.normal.resize(n);
    g.e1.resize(n);
    g.e2.resize(n);
    g.variation.resize(n);
    if (!points.color.empty()) g.color_gradient.assign(n, Eigen::Vector3d::Zero());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const Eigen::Vector3d& p = points.position[i];
            const std::uint32_t* nb = graph.index.data() + graph.offset[i];
            const std::size_t m = graph.degree(i);
            Eigen::Vector3d mean = p;
            for (std::size_t j = 0; j < m; ++j) mean += points.position[nb[j]];
            mean /= static_cast<double>(m + 1);
            Eigen::Matrix3d cov = (p - mean) * (p - mean).transpose();
            for (std::size_t j = 0; j < m; ++j) {
                const Eigen::Vector3d d = points.position[nb[j]] - mean;
                cov += d * d.transpose();
            }
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
            eig.computeDirect(cov);
            const Eigen::Vector3d l = eig.eigenvalues().cwiseMax(0.0);
            const double sum = l.sum();
            g.variation[i] = sum > 0 ? static_cast<float>(l[0] / sum) : 0.0f;
            Eigen::Vector3d normal;
            if (given) {
                normal = points.normal[i].normalized();
            } else {
                normal = eig.eigenvectors().col(0).normalized();
                if (m < 2 || !normal.allFinite()) normal = Eigen::Vector3d::UnitZ();
                Eigen::Vector3d towards = p - centroid;
                if (!points.view.empty() && points.view[i] >= 0 &&
                    points.view[i] < static_cast<int>(sensors.size()))
                    towards = sensors[points.view[i]].world_from_sensor.translation() - p;
                if (normal.dot(towards) < 0) normal = -normal;
            }
            g.normal[i] = normal;
            g.e1[i] = orthogonal(normal);
            g.e2[i] = normal.cross(g.e1[i]);
            if (!points.color.empty()) {
                auto intensity = [&](std::uint32_t q) {
                    const Rgb& c = points.color[q];
                    return (double(c.r) + c.g + c.b) / 3.0;
                };
                const double ip = intensity(static_cast<std::uint32_t>(i));
                Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
                Eigen::Vector2d b = Eigen::Vector2d::Zero();
                for (std::size_t j = 0; j < m; ++j) {
                    const Eigen::Vector3d d = points.position[nb[j]] - p;
                    const Eigen::Vector2d x(d.dot(g.e1[i]), d.dot(g.e2[i]));
                    a += x * x.transpose();
                    b += x * (intensity(nb[j]) - ip);
                }
                if (std::abs(a.determinant()) > 1e-30) {
                    const Eigen::Vector2d d2 = a.ldlt().solve(b);
                    g.color_gradient[i] = d2.x() * g.e1[i] + d2.y() * g.e2[i];
                }
            }
        }
    });
    return g;
}

}  // namespace

SurfaceGradient compute_surface_gradient(const SurfacePoints& points, double spacing_m,
                                         const std::vector<SensorView>& sensors,
                                         const GradientOptions& options) {
    options.check();
    check_points(points);
    return gradient_over(points,
                         build_neighbourhood(points.position, spacing_m, options.neighbourhood),
                         sensors, options);
}

PointCriteria point_criteria(const Eigen::Vector3d& p, const Eigen::Vector3d& e1,
                             const Eigen::Vector3d& e2, const std::vector<Eigen::Vector3d>& all,
                             const std::uint32_t* neighbours, std::size_t count,
                             const BoundaryOptions& options) {
    PointCriteria c;
    if (count < 2) {
        c.p_angle = c.p_halfdisk = 1.0f;
        c.probability =
            static_cast<float>((options.w_angle + options.w_halfdisk) /
                               (options.w_angle + options.w_halfdisk + options.w_shape));
        return c;
    }
    // Projected coordinates; small fixed buffers (neighbour sets are capped by the caller).
    thread_local std::vector<std::pair<double, std::uint32_t>> angles;
    thread_local std::vector<Eigen::Vector2d> xy;
    angles.clear();
    xy.clear();
    double rbar = 0, rmax = 0;
    for (std::size_t j = 0; j < count; ++j) {
        const Eigen::Vector3d d = all[neighbours[j]] - p;
        const Eigen::Vector2d x(d.dot(e1), d.dot(e2));
        xy.push_back(x);
        const double rho = x.norm();
        rbar += rho;
        rmax = std::max(rmax, rho);
        angles.emplace_back(std::atan2(x.y(), x.x()), neighbours[j]);
    }
    rbar /= static_cast<double>(count);
    // Angle criterion: the largest gap between consecutive directions (wrap-around included).
    std::sort(angles.begin(), angles.end());
    double gap = angles.front().first + 2 * M_PI - angles.back().first;
    std::size_t gap_end = 0;  // the gap runs from angles[gap_end - 1] to angles[gap_end]
    for (std::size_t j = 1; j < angles.size(); ++j) {
        const double g = angles[j].first - angles[j - 1].first;
        if (g > gap) {
            gap = g;
            gap_end = j;
        }
    }
    c.gap_a = angles[(gap_end + angles.size() - 1) % angles.size()].second;
    c.gap_b = angles[gap_end].second;
    const double even = 2 * M_PI / static_cast<double>(count);
    c.p_angle = static_cast<float>(std::clamp((gap - even) / (M_PI - even), 0.0, 1.0));
    // Half-disk criterion: Gaussian-weighted centroid against the half-disc centroid 4R/(3 pi).
    Eigen::Vector2d mu = Eigen::Vector2d::Zero();
    double wsum = 0;
    const double r2 = std::max(rbar * rbar, 1e-300);
    for (const auto& x : xy) {
        const double w = std::exp(-x.squaredNorm() / r2);
        mu += w * x;
        wsum += w;
    }
    mu /= wsum;
    const double half = 4.0 * rmax / (3.0 * M_PI);
    c.p_halfdisk = static_cast<float>(half > 0 ? std::min(mu.norm() / half, 1.0) : 0.0);
    // Shape criterion: normalised eigenvalues of the projected neighbourhood (p included)
    // about its centroid, against the ideal boundary signature.
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& x : xy) mean += x;
    mean /= static_cast<double>(count + 1);
    Eigen::Matrix2d cov = mean * mean.transpose();
    for (const auto& x : xy) cov += (x - mean) * (x - mean).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig;
    eig.computeDirect(cov);
    const double l0 = std::max(eig.eigenvalues()[1], 0.0), l1 = std::max(eig.eigenvalues()[0], 0.0);
    const double sum = l0 + l1;
    if (sum > 0) {
        const double a = l0 / sum - options.lambda_b0, b = l1 / sum - options.lambda_b1;
        const double ia = 0.5 - options.lambda_b0, ib = 0.5 - options.lambda_b1;
        const double sigma2 = std::max(ia * ia + ib * ib, 1e-6);
        c.p_shape = static_cast<float>(std::exp(-(a * a + b * b) / sigma2));
    }
    const double wsum_all = options.w_angle + options.w_halfdisk + options.w_shape;
    c.probability =
        static_cast<float>((options.w_angle * c.p_angle + options.w_halfdisk * c.p_halfdisk +
                            options.w_shape * c.p_shape) /
                           wsum_all);
    return c;
}

bool sensor_sees_region(const SensorView& sensor, const Eigen::Vector3d& centre,
                        const Eigen::Vector3d& normal, double radius_m, double spacing,
                        const internal::KdTree& tree, double max_angle_deg, double ray_clearance) {
    const Eigen::Vector3d s = sensor.world_from_sensor.translation();
    const Eigen::Vector3d to_sensor = s - centre;
    const double dist = to_sensor.norm();
    if (dist <= 0) return false;
    const Eigen::Vector3d dir = to_sensor / dist;
    if (std::abs(dir.dot(normal)) < std::cos(max_angle_deg * M_PI / 180.0)) return false;
    if (sensor.intrinsics) {
        const Eigen::Vector3d c = sensor.world_from_sensor.inverse() * centre;
        if (c.z() <= 0) return false;
        const auto& k = *sensor.intrinsics;
        const double u = k.fx * c.x() / c.z() + k.cx, v = k.fy * c.y() / c.z() + k.cy;
        if (u < 0 || v < 0 || u > k.width - 1 || v > k.height - 1) return false;
    }
    // March from the region towards the sensor; the first stretch (inside the hole, where the
    // ray leaves the surface) is skipped up to where the ray has cleared the rim.
    const double clearance = ray_clearance * spacing;
    const double start = std::max(0.5 * radius_m, 0.0) + 2.0 * clearance;
    std::uint32_t idx;
    double d2;
    for (double t = start; t < dist; t += clearance) {
        const Eigen::Vector3d q = centre + t * dir;
        if (tree.nearest_within(q, clearance * clearance, idx, d2)) return false;
    }
    return true;
}

BoundaryResult detect_boundaries(const SurfacePoints& points,
                                 const std::vector<SensorView>& sensors,
                                 const BoundaryOptions& options, Report* report,
                                 const Progress& progress) {
    options.check();
    check_points(points);
    Stopwatch watch;
    const std::size_t n = points.size();
    BoundaryResult r;
    // One kd-tree for everything below (a sequential build, beside the spacing's parallel
    // estimate), and the gradient's and the criteria's neighbourhoods from one pass of queries
    // (the same graphs as build_neighbourhood's, one per option set).
    std::optional<internal::KdTree> kd;
    tbb::parallel_invoke([&] { kd.emplace(points.position); },
                         [&] {
                             r.spacing_m = options.spacing_m > 0
                                               ? options.spacing_m
                                               : sampling::robust_spacing(points.position);
                         });
    RGBD_CHECK(r.spacing_m > 0, "holes: the points have zero spacing (all duplicates?)");
    const GradientOptions gradient_options;
    gradient_options.check();
    const internal::KdTree& tree = *kd;
    Neighbourhood graph;
    {
        std::vector<detail::Directed> directed =
            detail::directed_lists(points.position, tree, r.spacing_m,
                                   {gradient_options.neighbourhood, options.neighbourhood});
        if (!report_progress(progress, 0.2)) throw AlgorithmError("cancelled");
        // The two graphs side by side (their edge scatter is sequential).
        Neighbourhood gradient_graph;
        tbb::parallel_invoke(
            [&] {
                gradient_graph =
                    detail::graph_from(directed[0], gradient_options.neighbourhood.symmetric);
            },
            [&] { graph = detail::graph_from(directed[1], options.neighbourhood.symmetric); });
        r.gradient = gradient_over(points, gradient_graph, sensors, gradient_options);
        if (!report_progress(progress, 0.3)) throw AlgorithmError("cancelled");
    }
    if (!report_progress(progress, 0.5)) throw AlgorithmError("cancelled");
    r.p_angle.resize(n);
    r.p_halfdisk.resize(n);
    r.p_shape.resize(n);
    r.probability.resize(n);
    r.gap_a.resize(n);
    r.gap_b.resize(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const PointCriteria c = point_criteria(
                points.position[i], r.gradient.e1[i], r.gradient.e2[i], points.position,
                graph.index.data() + graph.offset[i], graph.degree(i), options);
            r.p_angle[i] = c.p_angle;
            r.p_halfdisk[i] = c.p_halfdisk;
            r.p_shape[i] = c.p_shape;
            r.probability[i] = c.probability;
            r.gap_a[i] = c.gap_a;
            r.gap_b[i] = c.gap_b;
        }
    });
    if (!report_progress(progress, 0.8)) throw AlgorithmError("cancelled");
    std::vector<std::uint8_t> candidate(n);
    std::size_t candidates = 0;
    for (std::size_t i = 0; i < n; ++i) {
        candidate[i] = r.probability[i] >= options.threshold;
        candidates += candidate[i];
    }
    // Coherence: a rim is a curve, so the neighbours bounding the gap must be candidates too
    // (both, or at least one: the default, see BoundaryOptions::coherence_both).
    for (int pass = 0; pass < options.coherence_passes; ++pass) {
        std::vector<std::uint8_t> next(candidate);
        bool changed = false;
        for (std::size_t i = 0; i < n; ++i)
            if (candidate[i] &&
                (r.gap_a[i] == kNone || r.gap_b[i] == kNone ||
                 (options.coherence_both ? !candidate[r.gap_a[i]] || !candidate[r.gap_b[i]]
                                         : !candidate[r.gap_a[i]] && !candidate[r.gap_b[i]]))) {
                next[i] = 0;
                changed = true;
            }
        candidate.swap(next);
        if (!changed) break;
    }
    std::size_t coherent = 0;
    for (auto c : candidate) coherent += c;
    // Loops: connected components of boundary points, linked along the neighbourhood graph and
    // within link_distance spacings (bridges the odd rim point that failed the threshold, like
    // closing chains in §10.8).
    r.boundary.assign(n, 0);
    std::vector<std::uint32_t> component(n, kNone);
    std::vector<std::uint32_t> stack;
    std::vector<Eigen::Vector3d> rim_positions;
    std::vector<std::uint32_t> rim_index;
    std::vector<std::uint32_t> rim_of(n, kNone);  ///< position of a candidate in rim_positions
    for (std::size_t i = 0; i < n; ++i)
        if (candidate[i]) {
            rim_of[i] = static_cast<std::uint32_t>(rim_positions.size());
            rim_positions.push_back(points.position[i]);
            rim_index.push_back(static_cast<std::uint32_t>(i));
        }
    // The rim points linked to each rim point, queried in parallel before the (sequential)
    // search; each list in the tree's order, as the search would have queried it.
    const internal::KdTree rim_tree(rim_positions);
    const std::size_t rims = rim_positions.size();
    std::vector<std::uint32_t> link_offset(rims + 1, 0), link_index;
    {
        constexpr std::size_t kChunk = 1024;
        const std::size_t chunks = (rims + kChunk - 1) / kChunk;
        std::vector<std::vector<std::uint32_t>> rows(chunks);
        tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t chunk) {
            std::vector<std::pair<std::uint32_t, double>> linked;
            const std::size_t end = std::min(rims, (chunk + 1) * kChunk);
            for (std::size_t k = chunk * kChunk; k < end; ++k) {
                rim_tree.radius(rim_positions[k], options.link_distance * r.spacing_m, linked,
                                /*sorted=*/false);
                for (const auto& [j, d2] : linked) rows[chunk].push_back(j);
                link_offset[k + 1] = static_cast<std::uint32_t>(linked.size());
            }
        });
        for (std::size_t k = 0; k < rims; ++k) link_offset[k + 1] += link_offset[k];
        link_index.resize(link_offset[rims]);
        tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t chunk) {
            std::copy(rows[chunk].begin(), rows[chunk].end(),
                      link_index.begin() + link_offset[chunk * kChunk]);
        });
    }
    std::vector<BoundaryLoop> found;
    for (std::size_t seed = 0; seed < n; ++seed) {
        if (!candidate[seed] || component[seed] != kNone) continue;
        BoundaryLoop loop;
        stack.assign(1, static_cast<std::uint32_t>(seed));
        const auto id = static_cast<std::uint32_t>(found.size());
        component[seed] = id;
        while (!stack.empty()) {
            const std::uint32_t i = stack.back();
            stack.pop_back();
            loop.points.push_back(i);
            const std::uint32_t k = rim_of[i];
            for (std::uint32_t e = link_offset[k]; e < link_offset[k + 1]; ++e) {
                const std::uint32_t j = rim_index[link_index[e]];
                if (component[j] == kNone) {
                    component[j] = id;
                    stack.push_back(j);
                }
            }
            for (std::uint32_t e = graph.offset[i]; e < graph.offset[i + 1]; ++e) {
                const std::uint32_t j = graph.index[e];
                if (candidate[j] && component[j] == kNone) {
                    component[j] = id;
                    stack.push_back(j);
                }
            }
        }
        if (static_cast<int>(loop.points.size()) < options.min_loop_points) {
            for (auto i : loop.points) component[i] = kNone - 1;  // noise, never revisited
            continue;
        }
        found.push_back(std::move(loop));
    }
    // Each loop's plane, size and visibility, the loops in parallel (independent).
    tbb::parallel_for(std::size_t(0), found.size(), [&](std::size_t l) {
        BoundaryLoop& loop = found[l];
        std::sort(loop.points.begin(), loop.points.end());
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (auto i : loop.points) mean += points.position[i];
        mean /= static_cast<double>(loop.points.size());
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
        double far = 0;
        for (auto i : loop.points) {
            const Eigen::Vector3d d = points.position[i] - mean;
            cov += d * d.transpose();
            normal_sum += r.gradient.normal[i];
            far = std::max(far, d.norm());
        }
        double diameter = 0;
        for (auto i : loop.points) {
            // Largest extent, approximated through the farthest point from the centre.
            diameter = std::max(diameter, (points.position[i] - mean).norm() * 2.0);
        }
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
        Eigen::Vector3d normal = eig.eigenvectors().col(0);
        // A rim that is nearly straight or tiny has no plane: fall back to the mean normal.
        if (eig.eigenvalues()[1] < 1e-3 * eig.eigenvalues()[2] && normal_sum.norm() > 0)
            normal = normal_sum.normalized();
        if (normal.dot(normal_sum) < 0) normal = -normal;
        loop.centre = mean;
        loop.normal = normal;
        loop.diameter_m = diameter;
        loop.small = diameter <= options.small_max_diameter * r.spacing_m &&
                     static_cast<int>(loop.points.size()) <= options.small_max_points;
        if (!sensors.empty()) {
            for (const SensorView& s : sensors)
                loop.seen_by +=
                    sensor_sees_region(s, loop.centre, loop.normal, far, r.spacing_m, tree,
                                       options.visible_max_angle_deg, options.ray_clearance)
                        ? 1
                        : 0;
            loop.kind = loop.seen_by > 0 ? HoleKind::kOpening : HoleKind::kOcclusion;
        }
    });
    for (auto& loop : found) {
        for (auto i : loop.points) r.boundary[i] = 1;
        r.loops.push_back(std::move(loop));
    }
    // Hysteresis [M]: rims grow into graph neighbours above the low threshold, a few rings at
    // most (rim points at sharp hole corners, where the gap is only ~90 degrees).
    std::size_t grown = 0;
    if (options.hysteresis_threshold > 0) {
        for (std::uint32_t l = 0; l < r.loops.size(); ++l) {
            std::vector<std::uint32_t> frontier = r.loops[l].points, next;
            for (int ring = 0; ring < options.hysteresis_rings && !frontier.empty(); ++ring) {
                next.clear();
                for (auto i : frontier)
                    for (std::uint32_t e = graph.offset[i]; e < graph.offset[i + 1]; ++e) {
                        const std::uint32_t j = graph.index[e];
                        if (r.boundary[j] || r.probability[j] < options.hysteresis_threshold)
                            continue;
                        r.boundary[j] = 1;
                        next.push_back(j);
                    }
                r.loops[l].points.insert(r.loops[l].points.end(), next.begin(), next.end());
                grown += next.size();
                frontier.swap(next);
            }
            std::sort(r.loops[l].points.begin(), r.loops[l].points.end());
        }
    }
    if (report) {
        std::size_t flagged = 0, small = 0, openings = 0, occlusions = 0;
        for (auto b : r.boundary) flagged += b;
        for (const auto& l : r.loops) {
            small += l.small;
            openings += l.kind == HoleKind::kOpening;
            occlusions += l.kind == HoleKind::kOcclusion;
        }
        (*report)["spacing_m"] = r.spacing_m;
        (*report)["points"] = n;
        (*report)["candidates"] = candidates;
        (*report)["after_coherence"] = coherent;
        (*report)["hysteresis_added"] = grown;
        (*report)["boundary_points"] = flagged;
        (*report)["loops"] = r.loops.size();
        (*report)["small_loops"] = small;
        (*report)["opening_loops"] = openings;
        (*report)["occlusion_loops"] = occlusions;
        (*report)["detect_time_s"] = watch.seconds();
    }
    report_progress(progress, 1.0);
    return r;
}

}  // namespace rgbd::holes
