#include "algorithms/holes/hole_filling.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

namespace {

constexpr EnumName<FillMechanism> kMechanismNames[] = {
    {FillMechanism::kOnePoint, "one"},         {FillMechanism::kFourPoints, "four"},
    {FillMechanism::kThreePoints, "three"},    {FillMechanism::kInterpolation, "interpolation"},
    {FillMechanism::kLargeHole, "large-hole"}, {FillMechanism::kHeadTop, "head-top"}};

/// What parse_fill_mechanism accepts: the small-hole mechanisms by name and by their number
/// M1..M4 (§11).
constexpr EnumName<FillMechanism> kSmallHoleNames[] = {
    {FillMechanism::kOnePoint, "one"},      {FillMechanism::kFourPoints, "four"},
    {FillMechanism::kThreePoints, "three"}, {FillMechanism::kInterpolation, "interpolation"},
    {FillMechanism::kOnePoint, "m1"},       {FillMechanism::kFourPoints, "m2"},
    {FillMechanism::kThreePoints, "m3"},    {FillMechanism::kInterpolation, "m4"}};

}  // namespace

const char* to_string(FillMechanism mechanism) {
    return name_of(kMechanismNames, mechanism, "interpolation");
}

FillMechanism parse_fill_mechanism(const std::string& name) {
    if (const auto mechanism = value_of(kSmallHoleNames, name)) return *mechanism;
    throw InputError("fill: unknown mechanism '" + name + "' (one, four, three or interpolation)");
}

void FillOptions::check() const {
    check_range("fill: step", step, Range::open_closed(0.05, 10));
    check_range("fill: quadric_k", quadric_k, Range::closed(6, 500));
    check_range("fill: color_k", color_k, Range::closed(1, 100));
    RGBD_CHECK(std::isfinite(duplicate_distance) && duplicate_distance > 0 &&
                   duplicate_distance < step * 1.5,
               "fill: duplicate distance must be in (0, 1.5 x step)");
    RGBD_CHECK(
        std::isfinite(max_fit_rms) && max_fit_rms > 0,
        "fill: the quadric's residual limit must be positive, got " + format_number(max_fit_rms));
    check_range("fill: max_sweeps", max_sweeps, Range::closed(1, 1000));
    check_range("fill: grid clearance", grid_clearance, Range::open_closed(0, 5), "spacings");
    check_range("fill: inside gap", inside_max_gap_deg, Range::open(30, 360), "degrees");
}

namespace {

Eigen::Vector3d orthogonal(const Eigen::Vector3d& n) {
    const Eigen::Vector3d axis =
        std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    return n.cross(axis).normalized();
}

/// A height field z = a x^2 + b xy + c y^2 + d x + e y + f in a local frame.
struct Quadric {
    Eigen::Vector3d origin, e1, e2, n;
    Eigen::Matrix<double, 6, 1> k = Eigen::Matrix<double, 6, 1>::Zero();

    /// Weighted least squares (Gaussian weights of the distance to the origin, sigma = the mean
    /// distance); falls back to a plane (d, e, f) when the quadric is ill-posed.
    bool fit(const std::vector<Eigen::Vector3d>& pts, const std::uint32_t* idx, std::size_t m) {
        if (m < 3) return false;
        double mean = 0;
        for (std::size_t j = 0; j < m; ++j) mean += (pts[idx[j]] - origin).norm();
        mean = std::max(mean / double(m), 1e-12);
        Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Zero();
        Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
        for (std::size_t j = 0; j < m; ++j) {
            const Eigen::Vector3d d = pts[idx[j]] - origin;
            const double x = d.dot(e1), y = d.dot(e2), z = d.dot(n);
            const double w = std::exp(-d.squaredNorm() / (mean * mean));
            Eigen::Matrix<double, 6, 1> row;
            row << x * x, x * y, y * y, x, y, 1.0;
            a += w * row * row.transpose();
            b += w * row * z;
        }
        k.setZero();
        if (m >= 8) {
            Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(a);
            const Eigen::Matrix<double, 6, 1> s = ldlt.solve(b);
            // Conditioning guard: the quadric must stay a mild height field over the patch.
            if (ldlt.info() == Eigen::Success && s.allFinite() &&
                std::abs(s[0]) + std::abs(s[1]) + std::abs(s[2]) < 10.0 / mean) {
                k = s;
                return true;
            }
        }
        const Eigen::Matrix3d a3 = a.bottomRightCorner<3, 3>();
        const Eigen::Vector3d s3 = a3.ldlt().solve(b.tail<3>());
        if (!s3.allFinite()) return false;
        k.tail<3>() = s3;
        return true;
    }
    /// Weighted RMS distance (the fit's weights) of the points to the fitted height field.
    double rms(const std::vector<Eigen::Vector3d>& pts, const std::uint32_t* idx,
               std::size_t m) const {
        double mean = 0;
        for (std::size_t j = 0; j < m; ++j) mean += (pts[idx[j]] - origin).norm();
        mean = std::max(mean / double(std::max<std::size_t>(m, 1)), 1e-12);
        double sum = 0, wsum = 0;
        for (std::size_t j = 0; j < m; ++j) {
            const Eigen::Vector3d d = pts[idx[j]] - origin;
            const double w = std::exp(-d.squaredNorm() / (mean * mean));
            const double r = d.dot(n) - height(d.dot(e1), d.dot(e2));
            sum += w * r * r;
            wsum += w;
        }
        return wsum > 0 ? std::sqrt(sum / wsum) : 0.0;
    }
    double height(double x, double y) const {
        return k[0] * x * x + k[1] * x * y + k[2] * y * y + k[3] * x + k[4] * y + k[5];
    }
    /// Lifts the point with local coordinates (x, y) onto the surface; writes its normal.
    Eigen::Vector3d lift(double x, double y, Eigen::Vector3d& normal) const {
        const double zx = 2 * k[0] * x + k[1] * y + k[3];
        const double zy = k[1] * x + 2 * k[2] * y + k[4];
        normal = (n - zx * e1 - zy * e2).normalized();
        return origin + x * e1 + y * e2 + height(x, y) * n;
    }
};

/// Largest angular gap (radians) of the directions from q to the points, in the plane (e1, e2).
double largest_gap(const Eigen::Vector3d& q, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2,
                   const std::vector<Eigen::Vector3d>& rim, std::vector<double>& angles) {
    angles.clear();
    for (const auto& r : rim) {
        const Eigen::Vector3d d = r - q;
        angles.push_back(std::atan2(d.dot(e2), d.dot(e1)));
    }
    if (angles.size() < 3) return 2 * M_PI;
    std::sort(angles.begin(), angles.end());
    double gap = angles.front() + 2 * M_PI - angles.back();
    for (std::size_t j = 1; j < angles.size(); ++j) gap = std::max(gap, angles[j] - angles[j - 1]);
    return gap;
}

/// A uniform hash grid of accepted points (duplicate test inside one sweep).
class HashGrid {
public:
    explicit HashGrid(double cell) : cell_(cell) {}
    void insert(const Eigen::Vector3d& p) { cells_[key(p)].push_back(p); }
    bool any_within(const Eigen::Vector3d& p, double r) const {
        const auto c = coords(p);
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    auto it = cells_.find(pack(c[0] + dx, c[1] + dy, c[2] + dz));
                    if (it == cells_.end()) continue;
                    for (const auto& q : it->second)
                        if ((q - p).squaredNorm() < r * r) return true;
                }
        return false;
    }

private:
    std::array<long long, 3> coords(const Eigen::Vector3d& p) const {
        return {static_cast<long long>(std::floor(p.x() / cell_)),
                static_cast<long long>(std::floor(p.y() / cell_)),
                static_cast<long long>(std::floor(p.z() / cell_))};
    }
    static long long pack(long long x, long long y, long long z) {
        return (x & 0x1fffff) | ((y & 0x1fffff) << 21) | ((z & 0x1fffff) << 42);
    }
    long long key(const Eigen::Vector3d& p) const {
        const auto c = coords(p);
        return pack(c[0], c[1], c[2]);
    }
    double cell_;
    std::unordered_map<long long, std::vector<Eigen::Vector3d>> cells_;
};

struct LoopRegion {
    std::uint32_t loop;
    Eigen::Vector3d centre, n, e1, e2;
    double radius;                     ///< region radius (hole radius + margin)
    std::vector<Eigen::Vector3d> rim;  ///< rim positions
};

/// A proposed point (before lifting) from a rim point in a sweep.
struct Proposal {
    std::uint32_t from;  ///< index into the combined array
    std::uint32_t region;
    Eigen::Vector3d q0;
    std::uint32_t color_a, color_b;  ///< gap-bounding neighbours (UINT32_MAX = IDW)
};

class Filler {
public:
    Filler(const SurfacePoints& points, const BoundaryResult& detection, const FillOptions& options)
        : points_(points),
          detection_(detection),
          options_(options),
          spacing_(detection.spacing_m),
          originals_(points.position) {}

    FillResult run(Report* report, const Progress& progress) {
        Stopwatch watch;
        for (std::uint32_t l = 0; l < detection_.loops.size(); ++l) {
            const BoundaryLoop& loop = detection_.loops[l];
            if (!loop.small) continue;
            if (loop.kind == HoleKind::kOpening && !options_.fill_openings) continue;
            LoopRegion region;
            region.loop = l;
            region.centre = loop.centre;
            region.n = loop.normal;
            region.e1 = orthogonal(loop.normal);
            region.e2 = loop.normal.cross(region.e1);
            region.radius = 0.5 * loop.diameter_m + 2.0 * spacing_;
            for (auto i : loop.points) region.rim.push_back(points_.position[i]);
            regions_.push_back(std::move(region));
        }
        FillResult result;
        if (options_.mechanism == FillMechanism::kInterpolation)
            interpolate(result, progress);
        else
            sweep(result, progress);
        std::vector<std::uint8_t> touched(detection_.loops.size(), 0);
        for (auto l : result.loop) touched[l] = 1;
        for (auto t : touched) result.loops_filled += t;
        if (report) {
            (*report)["mechanism"] = to_string(options_.mechanism);
            (*report)["loops_considered"] = regions_.size();
            (*report)["loops_filled"] = result.loops_filled;
            (*report)["points_added"] = result.position.size();
            (*report)["sweeps"] = result.sweeps;
            if (options_.mechanism == FillMechanism::kInterpolation) {
                (*report)["loops_skipped_poor_fit"] = poor_fit_;
                // How far the MLS projection moved the hole quadric's grid points, on average.
                (*report)["local_projection_shift_mean_m"] =
                    shifted_ ? shift_sum_ / double(shifted_) : 0.0;
            }
            (*report)["fill_time_s"] = watch.seconds();
        }
        return result;
    }

private:
    bool inside(const LoopRegion& region, const Eigen::Vector3d& q,
                std::vector<double>& scratch) const {
        if ((q - region.centre).norm() > region.radius) return false;
        return largest_gap(q, region.e1, region.e2, region.rim, scratch) <=
               options_.inside_max_gap_deg * M_PI / 180.0;
    }

    /// MLS projection (§11, common machinery): lifts q0 along n onto the quadric height field
    /// fitted to the quadric_k original points nearest to q0, in the frame (q0, n); writes the
    /// lifted point and its normal (on n's side). false when the fit fails.
    bool lift_local(const Eigen::Vector3d& q0, const Eigen::Vector3d& n, Eigen::Vector3d& q,
                    Eigen::Vector3d& normal, std::vector<std::uint32_t>& idx,
                    std::vector<double>& d2) const {
        idx.resize(options_.quadric_k);
        d2.resize(options_.quadric_k);
        const std::size_t m = originals_.knn(q0, options_.quadric_k, idx.data(), d2.data());
        Quadric quad;
        quad.origin = q0;
        quad.n = n;
        quad.e1 = orthogonal(n);
        quad.e2 = n.cross(quad.e1);
        if (!quad.fit(points_.position, idx.data(), m)) return false;
        q = quad.lift(0.0, 0.0, normal);
        if (normal.dot(n) < 0) normal = -normal;
        return q.allFinite() && normal.allFinite();
    }

    /// M1-M3: lift_local, refused when the point moves by a step or more.
    bool project(const Eigen::Vector3d& q0, const Eigen::Vector3d& n, Eigen::Vector3d& q,
                 Eigen::Vector3d& normal, std::vector<std::uint32_t>& idx,
                 std::vector<double>& d2) const {
        if (!lift_local(q0, n, q, normal, idx, d2)) return false;
        // On a smooth surface the lift from the tangent plane is tiny at one spacing; a larger
        // move means the quadric extrapolates wildly (noisy, one-sided fit): no point.
        return (q - q0).norm() < options_.step * spacing_;
    }

    Rgb idw_color(const Eigen::Vector3d& q, std::vector<std::uint32_t>& idx,
                  std::vector<double>& d2) const {
        if (points_.color.empty()) return {128, 128, 128};
        idx.resize(options_.color_k);
        d2.resize(options_.color_k);
        const std::size_t m = originals_.knn(q, options_.color_k, idx.data(), d2.data());
        double sum[3] = {0, 0, 0}, wsum = 0;
        for (std::size_t j = 0; j < m; ++j) {
            const double w = 1.0 / std::max(std::sqrt(d2[j]), 1e-6 * spacing_);
            const Rgb& c = points_.color[idx[j]];
            sum[0] += w * c.r;
            sum[1] += w * c.g;
            sum[2] += w * c.b;
            wsum += w;
        }
        auto level = [&](double v) {
            return static_cast<std::uint8_t>(std::clamp(std::lround(v / wsum), 0L, 255L));
        };
        return {level(sum[0]), level(sum[1]), level(sum[2])};
    }

    void interpolate(FillResult& result, const Progress& progress) {
        std::vector<std::uint32_t> idx;
        std::vector<double> d2, scratch;
        std::vector<std::pair<std::uint32_t, double>> within;
        const double dup = options_.grid_clearance * spacing_;
        for (std::size_t r = 0; r < regions_.size(); ++r) {
            const LoopRegion& region = regions_[r];
            // One quadric for the whole hole, fitted to the original points around it.
            originals_.radius(region.centre, region.radius + 3.0 * spacing_, within, false);
            idx.clear();
            for (const auto& w : within) idx.push_back(w.first);
            Quadric quad;
            quad.origin = region.centre;
            quad.n = region.n;
            quad.e1 = region.e1;
            quad.e2 = region.e2;
            if (!quad.fit(points_.position, idx.data(), idx.size())) continue;
            // A quadric that does not fit the surroundings (a crease behind an ear, two layers
            // meeting) would bridge the hole above the true surface: the hole stays open.
            const double fit_rms = quad.rms(points_.position, idx.data(), idx.size());
            if (fit_rms > options_.max_fit_rms * spacing_) {
                ++poor_fit_;
                continue;
            }
            // Hexagonal grid of spacing s over the rim's extent in the hole plane.
            const double h = options_.step * spacing_;
            const double extent = region.radius;
            const int rows = static_cast<int>(std::ceil(extent / (h * std::sqrt(3.0) / 2)));
            const int cols = static_cast<int>(std::ceil(extent / h)) + 1;
            for (int row = -rows; row <= rows; ++row) {
                const double y = row * h * std::sqrt(3.0) / 2;
                const double shift = (row & 1) ? 0.5 * h : 0.0;
                for (int col = -cols; col <= cols; ++col) {
                    const double x = col * h + shift;
                    Eigen::Vector3d normal;
                    Eigen::Vector3d q = quad.lift(x, y, normal);
                    if (!inside(region, q, scratch)) continue;
                    std::uint32_t nearest;
                    double nd2;
                    if (originals_.nearest_within(q, dup * dup, nearest, nd2)) continue;
                    // The hole's quadric chooses the points (inside the rim, clear of the
                    // measured ones); the measured points nearest to each put it on their
                    // surface (MLS projection, as every M1-M3 point): one quadric over a whole
                    // hole rounds off a crease or the mouth of a channel and bridges it in the
                    // air (the bear's armpit: 12% of a hole's points farther than 5 mm from the
                    // truth, none after).
                    if (options_.local_projection) {
                        Eigen::Vector3d local, local_normal;
                        if (lift_local(q, normal, local, local_normal, idx, d2)) {
                            shift_sum_ += (local - q).norm();
                            ++shifted_;
                            q = local;
                            normal = local_normal;
                        }
                    }
                    add(result, q, normal, idw_color(q, idx, d2), FillMechanism::kInterpolation,
                        region.loop);
                }
            }
            if (!report_progress(progress, double(r + 1) / regions_.size()))
                throw AlgorithmError("cancelled");
        }
    }

    void sweep(FillResult& result, const Progress& progress) {
        const double dup = options_.duplicate_distance * spacing_;
        BoundaryOptions criteria;  // the §10 defaults, recomputed locally after each sweep
        const NeighbourhoodOptions& nb = criteria.neighbourhood;
        for (int s = 0; s < options_.max_sweeps; ++s) {
            // All points so far: originals, then the added ones.
            std::vector<Eigen::Vector3d> all(points_.position);
            all.insert(all.end(), result.position.begin(), result.position.end());
            const std::size_t n_orig = points_.position.size();
            internal::KdTree tree(all);
            // Active points: everything inside a hole region.
            std::vector<std::pair<std::uint32_t, std::uint32_t>> active;  // (point, region)
            std::vector<std::pair<std::uint32_t, double>> within;
            for (std::uint32_t r = 0; r < regions_.size(); ++r) {
                tree.radius(regions_[r].centre, regions_[r].radius, within, false);
                for (const auto& w : within) active.emplace_back(w.first, r);
            }
            std::sort(active.begin(), active.end());
            active.erase(
                std::unique(active.begin(), active.end(),
                            [](const auto& a, const auto& b) { return a.first == b.first; }),
                active.end());
            // Proposals, computed in parallel, in a fixed slot per active point.
            std::vector<std::array<Proposal, 4>> slots(active.size());
            std::vector<int> counts(active.size(), 0);
            tbb::parallel_for(
                tbb::blocked_range<std::size_t>(0, active.size(), 64), [&](const auto& range) {
                    std::vector<std::uint32_t> idx(nb.k + 1);
                    std::vector<double> d2(nb.k + 1);
                    std::vector<std::pair<std::uint32_t, double>> rad;
                    std::vector<std::uint32_t> neighbours;
                    std::vector<std::pair<double, std::uint32_t>> angles;
                    for (std::size_t a = range.begin(); a != range.end(); ++a) {
                        const std::uint32_t i = active[a].first;
                        const Eigen::Vector3d& p = all[i];
                        const Eigen::Vector3d n =
                            i < n_orig ? detection_.gradient.normal[i] : result.normal[i - n_orig];
                        const Eigen::Vector3d e1 = orthogonal(n), e2 = n.cross(e1);
                        neighbours.clear();
                        const std::size_t found = tree.knn(p, nb.k + 1, idx.data(), d2.data());
                        for (std::size_t j = 0; j < found; ++j)
                            if (idx[j] != i) neighbours.push_back(idx[j]);
                        tree.radius(p, nb.radius_factor * spacing_, rad, true);
                        for (const auto& [j, dd] : rad)
                            if (j != i && neighbours.size() < std::size_t(nb.max_neighbours) &&
                                std::find(neighbours.begin(), neighbours.end(), j) ==
                                    neighbours.end())
                                neighbours.push_back(j);
                        const PointCriteria c = point_criteria(p, e1, e2, all, neighbours.data(),
                                                               neighbours.size(), criteria);
                        if (c.probability < criteria.threshold) continue;
                        // Gaps between consecutive projected neighbours, largest first.
                        angles.clear();
                        for (auto j : neighbours) {
                            const Eigen::Vector3d d = all[j] - p;
                            angles.emplace_back(std::atan2(d.dot(e2), d.dot(e1)), j);
                        }
                        std::sort(angles.begin(), angles.end());
                        struct Gap {
                            double size, start;
                            std::uint32_t a, b;
                        };
                        std::vector<Gap> gaps;
                        for (std::size_t j = 0; j < angles.size(); ++j) {
                            const auto& prev = angles[(j + angles.size() - 1) % angles.size()];
                            double g = angles[j].first - prev.first;
                            if (j == 0) g += 2 * M_PI;
                            gaps.push_back({g, prev.first, prev.second, angles[j].second});
                        }
                        std::sort(gaps.begin(), gaps.end(),
                                  [](const Gap& x, const Gap& y) { return x.size > y.size; });
                        const double h = options_.step * spacing_;
                        auto propose = [&](double psi, std::uint32_t ca, std::uint32_t cb) {
                            Proposal& pr = slots[a][counts[a]++];
                            pr.from = i;
                            pr.region = active[a].second;
                            pr.q0 = p + h * (std::cos(psi) * e1 + std::sin(psi) * e2);
                            pr.color_a = ca;
                            pr.color_b = cb;
                        };
                        const double deg = M_PI / 180.0;
                        switch (options_.mechanism) {
                            case FillMechanism::kOnePoint:
                                if (gaps[0].size > 90 * deg)
                                    propose(gaps[0].start + gaps[0].size / 2, gaps[0].a, gaps[0].b);
                                break;
                            case FillMechanism::kFourPoints:
                                for (std::size_t g = 0; g < std::min<std::size_t>(4, gaps.size());
                                     ++g)
                                    if (gaps[g].size > 60 * deg)
                                        propose(gaps[g].start + gaps[g].size / 2, UINT32_MAX,
                                                UINT32_MAX);
                                break;
                            case FillMechanism::kThreePoints:
                                if (gaps[0].size > 120 * deg)
                                    for (int q = 1; q <= 3; ++q)
                                        propose(gaps[0].start + q * gaps[0].size / 4, gaps[0].a,
                                                gaps[0].b);
                                break;
                            default:
                                break;
                        }
                    }
                });
            // Accept in a fixed order (deterministic): lift, test, colour.
            HashGrid accepted(dup);
            std::vector<std::uint32_t> idx;
            std::vector<double> d2, scratch;
            std::size_t added = 0;
            for (std::size_t a = 0; a < active.size(); ++a)
                for (int c = 0; c < counts[a]; ++c) {
                    const Proposal& pr = slots[a][c];
                    const LoopRegion& region = regions_[pr.region];
                    const Eigen::Vector3d n = pr.from < n_orig ? detection_.gradient.normal[pr.from]
                                                               : result.normal[pr.from - n_orig];
                    Eigen::Vector3d q, normal;
                    if (!project(pr.q0, n, q, normal, idx, d2)) continue;
                    if (!inside(region, q, scratch)) continue;
                    std::uint32_t nearest;
                    double nd2;
                    if (tree.nearest_within(q, dup * dup, nearest, nd2)) continue;
                    if (accepted.any_within(q, dup)) continue;
                    Rgb color;
                    if (pr.color_a != UINT32_MAX && !points_.color.empty()) {
                        auto col = [&](std::uint32_t j) {
                            return j < n_orig ? points_.color[j] : result.color[j - n_orig];
                        };
                        const Rgb ca = col(pr.color_a), cb = col(pr.color_b);
                        color = {static_cast<std::uint8_t>((ca.r + cb.r + 1) / 2),
                                 static_cast<std::uint8_t>((ca.g + cb.g + 1) / 2),
                                 static_cast<std::uint8_t>((ca.b + cb.b + 1) / 2)};
                    } else {
                        color = idw_color(q, idx, d2);
                    }
                    accepted.insert(q);
                    add(result, q, normal, color, options_.mechanism, region.loop);
                    ++added;
                }
            result.sweeps = s + 1;
            if (!report_progress(progress, double(s + 1) / options_.max_sweeps))
                throw AlgorithmError("cancelled");
            if (added == 0) break;
        }
    }

    void add(FillResult& result, const Eigen::Vector3d& q, const Eigen::Vector3d& normal,
             const Rgb& color, FillMechanism mechanism, std::uint32_t loop) const {
        result.position.push_back(q);
        result.normal.push_back(normal);
        result.color.push_back(color);
        result.mechanism.push_back(mechanism);
        result.loop.push_back(loop);
    }

    const SurfacePoints& points_;
    const BoundaryResult& detection_;
    const FillOptions& options_;
    double spacing_;
    internal::KdTree originals_;
    int poor_fit_ = 0;         ///< M4 loops left open: the quadric does not fit their surroundings
    double shift_sum_ = 0;     ///< M4: summed moves of the MLS projection (metres)
    std::size_t shifted_ = 0;  ///< M4: grid points projected
    std::vector<LoopRegion> regions_;
};

}  // namespace

FillResult fill_small_holes(const SurfacePoints& points, const BoundaryResult& detection,
                            const FillOptions& options, Report* report, const Progress& progress) {
    options.check();
    RGBD_CHECK(detection.boundary.size() == points.size() &&
                   detection.gradient.normal.size() == points.size(),
               "fill: the detection result does not belong to these points");
    RGBD_CHECK(detection.spacing_m > 0, "fill: the detection result has no spacing");
    Filler filler(points, detection, options);
    return filler.run(report, progress);
}

}  // namespace rgbd::holes
