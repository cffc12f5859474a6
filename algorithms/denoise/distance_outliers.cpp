#include "algorithms/denoise/distance_outliers.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::denoise {

void DistanceOptions::check() const {
    check_range("distance outliers: theta_max", theta_max_deg, Range::open_closed(0.0, 89.0),
                "degrees");
    check_range("distance outliers: c_min", c_min, Range::closed(0, 24));
    check_range("distance outliers: line_sigmas", line_sigmas, Range::closed(0.0, 1000.0));
    check_range("distance outliers: dense_min", dense_min, Range::closed(0, 24));
    check_range("distance outliers: c_min_wide", c_min_wide, Range::closed(0, 48));
    check_range("distance outliers: keep_knn", keep_knn, Range::closed(0.0, 1000.0));
    check_range("distance outliers: keep_k", keep_k, Range::closed(1, kMaxKeepK));
    check_range("distance outliers: n_speckle", n_speckle, Range::closed(0, 10000000));
    check_range("distance outliers: k", k, Range::closed(1, 1000));
    check_range("distance outliers: alpha", alpha, Range::closed(0.0, 1000.0));
}

namespace {

/// kWeak: short of c_min supporters in 5 x 5, pending the 7 x 7 second chance.
enum Reason : std::uint8_t { kKeep = 0, kFlying = 1, kSpeckle = 2, kStatistical = 3, kWeak = 4 };

/// Half size of the support window (5 x 5 pixels).
constexpr int kWindow = 2;
/// Half size of the wide window (7 x 7 pixels): second-chance support and the kNN keep test.
constexpr int kWide = 3;

/// Focal length in pixels from horizontally adjacent pixels (x / z changes by 1 / f).
double estimate_focal(const std::vector<Eigen::Vector3d>& cam,
                      const std::vector<std::int32_t>& grid, int width, int height) {
    std::vector<double> f;
    for (int row = 0; row < height; ++row)
        for (int col = 0; col + 1 < width; ++col) {
            const std::int32_t a = grid[std::size_t(row) * width + col];
            const std::int32_t b = grid[std::size_t(row) * width + col + 1];
            if (a < 0 || b < 0 || cam[a].z() <= 0.0 || cam[b].z() <= 0.0) continue;
            const double d = cam[b].x() / cam[b].z() - cam[a].x() / cam[a].z();
            if (d > 0.0) f.push_back(1.0 / d);
        }
    return lower_median(f);
}

/// The view's points on its pixel grid, in the camera frame.
struct PixelGrid {
    int width = 0, height = 0;
    std::vector<Eigen::Vector3d> cam;   ///< camera-frame coordinates: depth is the camera z
    std::vector<std::int32_t> grid;     ///< point per pixel (the first in cloud order; -1 none)
    std::vector<std::uint8_t> on_grid;  ///< 1 = the point is its pixel's point

    /// The point at pixel (rr, cc), -1 outside the grid or without a point.
    std::int32_t at(int rr, int cc) const {
        if (rr < 0 || rr >= height || cc < 0 || cc >= width) return -1;
        return grid[std::size_t(rr) * width + cc];
    }
};

/// Puts the live points `g` of the view on its pixel grid, in the camera frame; a point behind
/// the sensor (no surface there) gets reason kStatistical and stays off the grid.
PixelGrid pixel_grid(const PointCloud& cloud, const detail::Gathered& g,
                     const PointCloud::Uint32Map& pixel, const std::string& name,
                     std::vector<std::uint8_t>& reason) {
    const std::size_t n = g.xyz.size();
    PixelGrid pg;
    pg.cam = g.xyz;
    if (cloud.view.frame == ViewFrame::kWorld) {
        const Pose sensor_from_world = detail::sensor_from_world(cloud, name, "--distance");
        for (auto& p : pg.cam) p = sensor_from_world * p;
    }
    pg.width = cloud.view.grid_width;
    pg.height = cloud.view.grid_height;
    const std::size_t cells = std::size_t(pg.width) * std::size_t(pg.height);
    pg.grid.assign(cells, -1);
    pg.on_grid.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t px = pixel[g.ids[i]];
        if (pg.cam[i].z() <= 0.0) {
            reason[i] = kStatistical;  // behind the sensor: no surface there
            continue;
        }
        if (px < cells && pg.grid[px] < 0) {
            pg.grid[px] = static_cast<std::int32_t>(i);
            pg.on_grid[i] = 1;
        }
    }
    return pg;
}

/// The focal length in pixels: the view's intrinsics' mean of fx and fy, else estimated from
/// adjacent pixels. InputError naming the view when neither gives a finite positive value.
double view_focal(const PointCloud& cloud, const PixelGrid& pg, const std::string& name) {
    double focal = 0.0;
    if (cloud.view.intrinsics)
        focal = 0.5 * (cloud.view.intrinsics->fx + cloud.view.intrinsics->fy);
    else
        focal = estimate_focal(pg.cam, pg.grid, pg.width, pg.height);
    RGBD_CHECK(
        std::isfinite(focal) && focal > 0.0,
        name + ": cannot determine the focal length (no intrinsics, too few adjacent pixels)");
    return focal;
}

/// The window tests of pass A on one view's grid: the step-1 support relation, its 5 x 5 and
/// 7 x 7 counts, the step-2 straight-line test and the step-2b kNN distance.
class WindowTests {
public:
    WindowTests(const PixelGrid& pg, double focal, double theta_max, const DistanceOptions& options)
        : pg_(pg),
          focal_(focal),
          options_(options),
          step_(pg.cam.size(), 0.0),
          sigma_(pg.cam.size(), 0.0) {
        const double inv_cos = 1.0 / std::cos(theta_max);
        // Per point: the support radius per pixel of offset and sigma_z(z) head-on.
        tbb::parallel_for(std::size_t(0), pg.cam.size(), [&](std::size_t i) {
            if (pg.cam[i].z() <= 0.0) return;
            step_[i] = pg.cam[i].z() / focal * inv_cos;
            sigma_[i] = sigma_z_m(options.noise_model, pg.cam[i].z(), 0.0);
        });
        // |o| of every wide-window offset, computed once (the same values as inline sqrt calls).
        for (int dr = -kWide; dr <= kWide; ++dr)
            for (int dc = -kWide; dc <= kWide; ++dc)
                offset_norm_[dr + kWide][dc + kWide] = std::sqrt(double(dr * dr + dc * dc));
    }

    /// Does j, at pixel offset (dr, dc) from i, support i? A neighbour at pixel offset o on a
    /// real surface seen at incidence <= theta_max lies within |o| s_d(z) / cos(theta_max) +
    /// 3 sigma_z(z) in 3D (the step-1 relation).
    bool supports(std::int32_t i, std::int32_t j, int dr, int dc) const {
        const double limit = step_[i] * offset_norm_[dr + kWide][dc + kWide] + 3.0 * sigma_[i];
        return (pg_.cam[j] - pg_.cam[i]).squaredNorm() <= limit * limit;
    }

    /// visit(j, dr, dc) for every valid pixel j of the (2 half + 1)^2 window around (row, col),
    /// the centre excluded: the 5 x 5 window of the hot loop (inlined there) and the 7 x 7 one
    /// of the rare paths after it.
    template <class Visit>
    __attribute__((always_inline)) void each_in_window(int half, int row, int col,
                                                       const Visit& visit) const {
        for (int dr = -half; dr <= half; ++dr)
            for (int dc = -half; dc <= half; ++dc) {
                if (dr == 0 && dc == 0) continue;
                const int rr = row + dr, cc = col + dc;
                if (rr < 0 || rr >= pg_.height || cc < 0 || cc >= pg_.width) continue;
                const std::int32_t j = pg_.grid[std::size_t(rr) * pg_.width + cc];
                if (j >= 0) visit(j, dr, dc);
            }
    }

    /// Steps 1 and 2 for point i at (row, col): kWeak when it has fewer than c_min supporters
    /// in its 5 x 5 window, kFlying when the window is dense (dense_min valid pixels) and i
    /// continues no straight depth line, else kKeep.
    __attribute__((always_inline)) Reason window_verdict(std::int32_t i, int row, int col) const {
        int support = 0, valid = 0;
        // supports(i, j, dr, dc), written out: GCC does not inline it here since it has 4
        // callers (+20% instructions).
        const auto tally = [&](std::int32_t j, int dr, int dc) __attribute__((always_inline)) {
            ++valid;
            const double limit = step_[i] * offset_norm_[dr + kWide][dc + kWide] + 3.0 * sigma_[i];
            if ((pg_.cam[j] - pg_.cam[i]).squaredNorm() <= limit * limit) ++support;
        };
        each_in_window(kWindow, row, col, tally);
        if (support < options_.c_min) return kWeak;
        if (options_.line_sigmas > 0.0 && valid >= options_.dense_min &&
            !continues_line(i, row, col))
            return kFlying;
        return kKeep;
    }

    /// Step 1, second chance: supporters of i in its 7 x 7 window (the same relation).
    int wide_support(std::int32_t i, int row, int col) const {
        int count = 0;
        each_in_window(kWide, row, col, [&](std::int32_t j, int dr, int dc) {
            if (supports(i, j, dr, dc)) ++count;
        });
        return count;
    }

    /// Valid pixels in the 5 x 5 window around (row, col), the centre excluded.
    int window_points(int row, int col) const {
        int valid = 0;
        each_in_window(kWindow, row, col, [&](std::int32_t, int, int) { ++valid; });
        return valid;
    }

    /// Step 2b, kNN keep: mean 3D distance from i to its keep_k nearest points in its 7 x 7
    /// window, in pixel footprints z / f (infinity with fewer than keep_k valid pixels).
    double knn_footprints(std::int32_t i, int row, int col) const {
        const int keep_k = options_.keep_k;
        double best[DistanceOptions::kMaxKeepK];  // the keep_k smallest squared distances,
                                                  // ascending
        int found = 0;
        each_in_window(kWide, row, col, [&](std::int32_t j, int, int) {
            const double d = (pg_.cam[j] - pg_.cam[i]).squaredNorm();
            if (found == keep_k && d >= best[keep_k - 1]) return;
            int at = found < keep_k ? found++ : keep_k - 1;
            while (at > 0 && best[at - 1] > d) {
                best[at] = best[at - 1];
                --at;
            }
            best[at] = d;
        });
        if (found < keep_k) return std::numeric_limits<double>::infinity();
        double sum = 0.0;
        for (int a = 0; a < keep_k; ++a) sum += std::sqrt(best[a]);
        return sum / double(keep_k) / (pg_.cam[i].z() / focal_);
    }

    /// Step 2: does p (point i at row, col) continue a straight depth line along a grid axis
    /// (interpolation between both sides or extrapolation from one), within line_sigmas
    /// sigma_z(z) of the second difference?
    __attribute__((always_inline)) bool continues_line(std::int32_t i, int row, int col) const {
        constexpr int axes[4][2] = {{0, 1}, {1, 0}, {1, 1}, {1, -1}};
        const double z = pg_.cam[i].z();
        // Second-difference noise: sqrt(1.5) sigma for the midpoint of two neighbours,
        // sqrt(6) sigma for the extrapolation from one side.
        const double t_in = options_.line_sigmas * sigma_[i] * std::sqrt(1.5);
        const double t_ex = options_.line_sigmas * sigma_[i] * std::sqrt(6.0);
        for (const auto& a : axes) {
            const double zp = depth_at(row + a[0], col + a[1]);
            const double zm = depth_at(row - a[0], col - a[1]);
            const double zpp = depth_at(row + 2 * a[0], col + 2 * a[1]);
            const double zmm = depth_at(row - 2 * a[0], col - 2 * a[1]);
            // Comparisons with NaN are false: a missing sample never supports.
            if (std::abs(z - 0.5 * (zp + zm)) <= t_in || std::abs(z - (2.0 * zp - zpp)) <= t_ex ||
                std::abs(z - (2.0 * zm - zmm)) <= t_ex)
                return true;
        }
        return false;
    }

private:
    /// Depth at pixel (rr, cc), NaN outside the grid or without a point.
    __attribute__((always_inline)) double depth_at(int rr, int cc) const {
        if (rr < 0 || rr >= pg_.height || cc < 0 || cc >= pg_.width)
            return std::numeric_limits<double>::quiet_NaN();
        const std::int32_t j = pg_.grid[std::size_t(rr) * pg_.width + cc];
        return j < 0 ? std::numeric_limits<double>::quiet_NaN() : pg_.cam[j].z();
    }

    const PixelGrid& pg_;
    const double focal_;
    const DistanceOptions& options_;
    std::vector<double> step_, sigma_;
    double offset_norm_[2 * kWide + 1][2 * kWide + 1];
};

/// Steps 1 and 2 over every pixel (the hot loop: a few hundred pixels get flagged): the
/// window verdict of every grid point into `reason`.
void flag_by_window(const WindowTests& tests, const PixelGrid& pg,
                    std::vector<std::uint8_t>& reason) {
    tbb::parallel_for(tbb::blocked_range<int>(0, pg.height, 8),
                      [&](const tbb::blocked_range<int>& r) {
                          for (int row = r.begin(); row != r.end(); ++row)
                              for (int col = 0; col < pg.width; ++col) {
                                  const std::int32_t i = pg.grid[std::size_t(row) * pg.width + col];
                                  if (i < 0) continue;
                                  const Reason verdict = tests.window_verdict(i, row, col);
                                  if (verdict != kKeep) reason[i] = verdict;
                              }
                      });
}

/// The flagged pixels: the 7 x 7 second chance of step 1 (c_min_wide supporters, then step 2)
/// for the weak ones, which otherwise become flying, and step 2b for all (a flagged pixel is
/// kept when its nearest 3D points are close). Returns how many step 2b kept.
std::size_t second_chances(const WindowTests& tests, const PixelGrid& pg, const detail::Gathered& g,
                           const PointCloud::Uint32Map& pixel, const DistanceOptions& options,
                           std::vector<std::uint8_t>& reason) {
    const std::size_t n = g.xyz.size();
    const int width = pg.width;
    std::vector<std::uint32_t> flagged;
    for (std::size_t i = 0; i < n; ++i)
        if (pg.on_grid[i] && (reason[i] == kWeak || reason[i] == kFlying))
            flagged.push_back(static_cast<std::uint32_t>(i));
    std::atomic<std::size_t> kept_by_knn{0};
    tbb::parallel_for(std::size_t(0), flagged.size(), [&](std::size_t a) {
        const std::uint32_t i = flagged[a];
        const std::uint32_t px = pixel[g.ids[i]];
        const int row = int(px / std::uint32_t(width)), col = int(px % std::uint32_t(width));
        if (reason[i] == kWeak) {
            reason[i] = kFlying;
            if (options.c_min_wide > 0 &&
                tests.wide_support(std::int32_t(i), row, col) >= options.c_min_wide) {
                if (options.line_sigmas <= 0.0 ||
                    tests.window_points(row, col) < options.dense_min ||
                    tests.continues_line(std::int32_t(i), row, col)) {
                    reason[i] = kKeep;
                    return;
                }
            }
        }
        // Step 2b: a flagged pixel is kept when its nearest 3D points are close.
        if (options.keep_knn > 0.0 &&
            tests.knn_footprints(std::int32_t(i), row, col) <= options.keep_knn) {
            reason[i] = kKeep;
            kept_by_knn.fetch_add(1, std::memory_order_relaxed);
        }
    });
    return kept_by_knn.load();
}

/// Components of the grid graph over the survivors: root of every surviving grid point (n for
/// the others). Links: the window-support relation of step 1 (5 x 5, 3D distance), so that
/// grazing surface broken by dropouts stays one component.
std::vector<std::uint32_t> survivor_components(const WindowTests& tests, const PixelGrid& pg,
                                               const std::vector<std::uint8_t>& reason) {
    const std::size_t n = pg.cam.size();
    const int width = pg.width, height = pg.height, w = kWindow;
    detail::DisjointSets sets(n);
    for (int row = 0; row < height; ++row)
        for (int col = 0; col < width; ++col) {
            const std::int32_t i = pg.grid[std::size_t(row) * width + col];
            if (i < 0 || reason[i] != kKeep) continue;
            for (int dr = 0; dr <= w; ++dr)
                for (int dc = -w; dc <= w; ++dc) {
                    if (dr == 0 && dc <= 0) continue;  // each pair once
                    const int rr = row + dr, cc = col + dc;
                    if (rr >= height || cc < 0 || cc >= width) continue;
                    const std::int32_t j = pg.grid[std::size_t(rr) * width + cc];
                    if (j < 0 || reason[j] != kKeep || !tests.supports(i, j, dr, dc)) continue;
                    sets.unite(std::uint32_t(i), std::uint32_t(j));
                }
        }
    std::vector<std::uint32_t> root(n, std::uint32_t(n));
    for (std::size_t i = 0; i < n; ++i)
        if (pg.on_grid[i] && reason[i] == kKeep) root[i] = sets.find(std::uint32_t(i));
    return root;
}

/// Outcome of the speckle step.
struct SpeckleCount {
    std::size_t speckle = 0;     ///< points flagged
    std::size_t components = 0;  ///< components of the survivors
};

/// Step 3: speckles = small components (under n_speckle points, not the largest) of the grid
/// graph over the survivors, flagged kSpeckle, unless attached to a large component.
SpeckleCount flag_speckles(const WindowTests& tests, const PixelGrid& pg, const detail::Gathered& g,
                           const PointCloud::Uint32Map& pixel, int n_speckle,
                           std::vector<std::uint8_t>& reason) {
    const std::size_t n = pg.cam.size();
    const int width = pg.width, height = pg.height, ww = kWide;
    SpeckleCount result;
    // Root of every surviving grid point (n for the others), and component sizes.
    const std::vector<std::uint32_t> root = survivor_components(tests, pg, reason);
    std::vector<std::uint32_t> size(n, 0);
    for (std::size_t i = 0; i < n; ++i)
        if (root[i] != n) ++size[root[i]];
    std::uint32_t largest = 0;
    for (std::size_t i = 0; i < n; ++i) {
        if (size[i] > 0) ++result.components;
        if (size[i] > size[largest]) largest = static_cast<std::uint32_t>(i);
    }
    const auto small = [&](std::uint32_t c) {
        return c != largest && size[c] < std::uint32_t(n_speckle);
    };
    // A small component with a pixel that a pixel of a large one supports (relation 1) in its
    // 7 x 7 window is surface cut off by flagged pixels or dropouts, not a speckle (5 x 5 links
    // alone: rgbd-synth's wreath bust lost 0.20% of its surface instead of 0.12%, most of it as
    // such fragments). Only the few pixels of small components look (7 x 7 links for every
    // pixel made the whole filter ~30% slower). Repeated while fragments attach to fragments
    // attached in an earlier round.
    std::vector<std::uint8_t> attached(n, 0);
    for (bool changed = true; changed;) {
        changed = false;
        for (std::size_t i = 0; i < n; ++i) {
            if (root[i] == n || !small(root[i]) || attached[root[i]]) continue;
            const std::uint32_t px = pixel[g.ids[i]];
            const int row = int(px / std::uint32_t(width)), col = int(px % std::uint32_t(width));
            for (int dr = -ww; dr <= ww && !attached[root[i]]; ++dr)
                for (int dc = -ww; dc <= ww; ++dc) {
                    const int rr = row + dr, cc = col + dc;
                    if (rr < 0 || rr >= height || cc < 0 || cc >= width) continue;
                    const std::int32_t j = pg.grid[std::size_t(rr) * width + cc];
                    if (j < 0 || root[j] == n || root[j] == root[i] ||
                        (small(root[j]) && !attached[root[j]]) ||
                        !tests.supports(std::int32_t(i), j, dr, dc))
                        continue;
                    attached[root[i]] = 1;
                    changed = true;
                    break;
                }
        }
    }
    for (std::size_t i = 0; i < n; ++i)
        if (root[i] != n && small(root[i]) && !attached[root[i]]) {
            reason[i] = kSpeckle;
            ++result.speckle;
        }
    return result;
}

/// Pass B: the kNN test relative to the pixel footprint. Each survivor's mean distance to its
/// k nearest survivors in footprints z / f; flagged kStatistical above max(median + alpha
/// sigma_rob, median / cos(theta_max)) (recorded as r_median, r_sigma_rob, r_threshold).
/// Returns how many.
std::size_t flag_statistical(const std::vector<Eigen::Vector3d>& cam, double focal,
                             double theta_max, const DistanceOptions& options,
                             std::vector<std::uint8_t>& reason, Report& report) {
    const std::size_t n = cam.size();
    std::size_t statistical = 0;
    std::vector<std::uint32_t> alive;
    alive.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
        if (reason[i] == kKeep) alive.push_back(static_cast<std::uint32_t>(i));
    const std::size_t m = alive.size();
    const std::size_t search = std::min<std::size_t>(std::size_t(options.k) + 1, m);
    if (search < 2) return 0;
    std::vector<Eigen::Vector3d> pts(m);
    for (std::size_t a = 0; a < m; ++a) pts[a] = cam[alive[a]];
    const internal::KdTree tree(pts);
    std::vector<double> ratio(m);
    detail::for_each_knn(
        tree, pts, search, 256,
        [&](std::size_t a, const std::uint32_t*, const double* sq, std::size_t found) {
            const double dbar = detail::mean_distance(sq, found, 1);
            ratio[a] = dbar * focal / pts[a].z();
        });
    std::vector<double> tmp(ratio);
    const double med = lower_median(tmp);
    for (double& t : tmp) t = std::abs(t - med);
    const double sigma = 1.4826 * lower_median(tmp);
    const double threshold = std::max(med + options.alpha * sigma, med / std::cos(theta_max));
    report["r_median"] = med;
    report["r_sigma_rob"] = sigma;
    report["r_threshold"] = threshold;
    for (std::size_t a = 0; a < m; ++a)
        if (ratio[a] > threshold) {
            reason[alive[a]] = kStatistical;
            ++statistical;
        }
    return statistical;
}

}  // namespace

Report remove_distance_outliers(PointCloud& cloud, const DistanceOptions& options,
                                const Progress& progress) {
    Stopwatch watch;
    Report report;
    const detail::Gathered g = detail::open_run(cloud, options, "distance", report);
    const std::size_t n = g.xyz.size();
    const std::string name = detail::view_name(cloud);
    if (n == 0) return detail::nothing_removed(std::move(report), watch);
    const auto pixel = detail::organised_pixels(
        cloud, name,
        "--distance needs an organised view (pixel grid); this view has none, use --density "
        "(after alignment) or --statistical",
        "--distance needs the `pixel` property of an organised view; use --density or "
        "--statistical");
    if (!report_progress(progress, 0.0)) return detail::cancelled(report, watch);

    std::vector<std::uint8_t> reason(n, kKeep);
    const PixelGrid pg = pixel_grid(cloud, g, pixel, name, reason);
    const double focal = view_focal(cloud, pg, name);
    report["focal_px"] = focal;
    const double theta_max = options.theta_max_deg * std::numbers::pi / 180.0;

    // Pass A. Step 1: window support; a pixel short of c_min supporters in 5 x 5 gets a second
    // chance in 7 x 7 (c_min_wide): grazing surface thinned by dropouts. Step 2: line support
    // where the window is dense (no silhouette, no dropout hole): along one of the 4 grid axes
    // the depth must continue a straight line through p; flying pixels between two surfaces
    // do not. Step 2b (kNN keep): a pixel flagged by 1 or 2 stays when the mean 3D distance to
    // its keep_k nearest points in the 7 x 7 window is <= keep_knn footprints s_d(z): a flying
    // pixel floats away from every surface, noisy surface pixels at grazing incidence, next to
    // dropouts or at creases (which fail 1 or 2) still have close 3D neighbours. Step 3:
    // speckles, small components of the survivors.
    std::size_t flying = 0;
    SpeckleCount speckles;
    if (options.pass_a) {
        const WindowTests tests(pg, focal, theta_max, options);
        flag_by_window(tests, pg, reason);
        report["kept_by_knn"] = second_chances(tests, pg, g, pixel, options, reason);
        flying = static_cast<std::size_t>(std::count(reason.begin(), reason.end(), kFlying));
        if (options.n_speckle > 0)
            speckles = flag_speckles(tests, pg, g, pixel, options.n_speckle, reason);
    }
    report["flying"] = flying;
    report["speckle"] = speckles.speckle;
    report["components"] = speckles.components;
    if (!report_progress(progress, 0.4)) return detail::cancelled(report, watch);

    std::size_t statistical = 0;
    if (options.pass_b)
        statistical = flag_statistical(pg.cam, focal, theta_max, options, reason, report);
    report["statistical"] = statistical;
    std::vector<std::uint8_t> outlier(n);
    for (std::size_t i = 0; i < n; ++i) outlier[i] = reason[i] != kKeep;
    detail::record_removed(report, detail::apply(cloud, g, outlier, options.mark), options.mark);
    return detail::finished(std::move(report), watch, progress);
}

}  // namespace rgbd::denoise
