#include "algorithms/denoise/density_outliers.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/spacing_sample.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {

void DensityOptions::check() const {
    RGBD_CHECK(std::isfinite(theta_max_deg) && theta_max_deg > 0.0 && theta_max_deg <= 89.0,
               "density outliers: theta_max must be in (0, 89] degrees");
    RGBD_CHECK(k >= 2 && k <= 1000, "density outliers: k must be in [2, 1000]");
    RGBD_CHECK(k_ref >= 1 && k_ref <= 10000, "density outliers: k_ref must be in [1, 10000]");
    RGBD_CHECK(std::isfinite(beta) && beta >= 0.0 && beta <= 100.0,
               "density outliers: beta must be in [0, 100]");
    RGBD_CHECK(std::isfinite(beta_local) && beta_local >= 0.0 && beta_local <= 100.0,
               "density outliers: beta_local must be in [0, 100]");
    RGBD_CHECK(
        std::isfinite(cluster_spacing) && cluster_spacing >= 0.0 && cluster_spacing <= 1000.0,
        "density outliers: cluster_spacing must be in [0, 1000]");
    RGBD_CHECK(std::isfinite(min_cluster_fraction) && min_cluster_fraction >= 0.0 &&
                   min_cluster_fraction <= 1.0,
               "density outliers: min_cluster_fraction must be in [0, 1]");
}

namespace {

/// Depth map of one view in its own camera, for the visibility test.
struct Camera {
    Pose sensor_from_world;
    PinholeIntrinsics intrinsics;
    double focal = 0.0;
    std::vector<float> depth;  ///< width * height, +inf = no return
};

/// Components of the eps graph over `pts` (p ~ q iff |p - q| <= eps), exactly, without a
/// radius search per point: points are binned in cells of side c = eps / sqrt(3) (any two
/// points of a cell are closer than eps, so a cell lies in one component) and only cells at
/// most 2 apart on every axis can hold a linked pair (3 cells apart means more than 2c > eps
/// on that axis); a pair of cells is tested point by point, stopping at the first link, and
/// skipped when both already share a component. Writes each point's component
/// label (a cell index, equal for the points of one component) to `label`. Returns false
/// without touching `label` when the grid would not fit 21 bits per axis.
constexpr std::uint64_t key_of(std::uint64_t x, std::uint64_t y, std::uint64_t z) {
    return (x << 42) | (y << 21) | z;
}
constexpr std::uint64_t kKeyMask = (std::uint64_t(1) << 21) - 1;

/// Points binned in cubic cells of side `cell` (cell coordinates offset by 2, so that
/// neighbour offsets -2..2 never underflow), sorted by cell key.
struct CellGrid {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;  ///< (cell key, point), sorted
    std::vector<std::uint64_t> keys;                             ///< unique cell keys, sorted
    std::vector<std::uint32_t> start;  ///< cell c's points: keyed[start[c], start[c + 1])

    /// False (grid left empty) when the extent needs more than 21 bits per axis.
    bool build(const std::vector<Eigen::Vector3d>& pts, double cell) {
        const std::size_t m = pts.size();
        if (!(cell > 0.0) || m == 0) return false;
        Eigen::Vector3d lo = pts[0], hi = pts[0];
        for (const auto& p : pts) {
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
        constexpr double kMaxCells = double(1 << 21) - 8.0;
        if (((hi - lo) / cell).maxCoeff() >= kMaxCells) return false;
        keyed.resize(m);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m, 4096),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t a = r.begin(); a != r.end(); ++a) {
                                  const Eigen::Vector3d c = (pts[a] - lo) / cell;
                                  keyed[a] = {
                                      key_of(std::uint64_t(c.x()) + 2, std::uint64_t(c.y()) + 2,
                                             std::uint64_t(c.z()) + 2),
                                      std::uint32_t(a)};
                              }
                          });
        std::sort(keyed.begin(), keyed.end());
        for (std::size_t a = 0; a < m; ++a)
            if (a == 0 || keyed[a].first != keyed[a - 1].first) {
                keys.push_back(keyed[a].first);
                start.push_back(std::uint32_t(a));
            }
        start.push_back(std::uint32_t(m));
        return true;
    }
    std::size_t cells() const { return keys.size(); }
};

bool eps_components(const std::vector<Eigen::Vector3d>& pts, double eps,
                    std::vector<std::uint32_t>& label) {
    const std::size_t m = pts.size();
    CellGrid grid;
    if (!grid.build(pts, eps / std::sqrt(3.0) * (1.0 - 1e-9))) return false;
    const auto& keyed = grid.keyed;
    const auto& keys = grid.keys;
    const auto& start = grid.start;
    const std::size_t cells = grid.cells();
    const double eps2 = eps * eps;
    detail::DisjointSets sets(cells);
    const auto linked = [&](std::size_t ca, std::size_t cb) {
        for (std::uint32_t i = start[ca]; i < start[ca + 1]; ++i)
            for (std::uint32_t j = start[cb]; j < start[cb + 1]; ++j)
                if ((pts[keyed[i].second] - pts[keyed[j].second]).squaredNorm() <= eps2)
                    return true;
        return false;
    };
    for (std::size_t ca = 0; ca < cells; ++ca) {
        const std::uint64_t x = keys[ca] >> 42, y = (keys[ca] >> 21) & kKeyMask,
                            z = keys[ca] & kKeyMask;
        // Cells after this one in key order: (dx, dy) > (0, 0), or dx = dy = 0 and dz > 0.
        for (int dx = 0; dx <= 2; ++dx)
            for (int dy = -2; dy <= 2; ++dy) {
                if (dx == 0 && dy < 0) continue;
                const int dz_min = dx == 0 && dy == 0 ? 1 : -2;
                const std::uint64_t first = key_of(x + dx, y + dy, z + dz_min);
                const std::uint64_t last = key_of(x + dx, y + dy, z + 2);
                auto it =
                    std::lower_bound(keys.begin() + std::ptrdiff_t(ca + 1), keys.end(), first);
                for (; it != keys.end() && *it <= last; ++it) {
                    const std::size_t cb = std::size_t(it - keys.begin());
                    if (sets.find(std::uint32_t(ca)) == sets.find(std::uint32_t(cb))) continue;
                    if (linked(ca, cb)) sets.unite(std::uint32_t(ca), std::uint32_t(cb));
                }
            }
    }
    label.assign(m, 0);
    for (std::size_t c = 0; c < cells; ++c) {
        const std::uint32_t root = sets.find(std::uint32_t(c));
        for (std::uint32_t i = start[c]; i < start[c + 1]; ++i) label[keyed[i].second] = root;
    }
    return true;
}

}  // namespace

Report remove_density_outliers(std::vector<PointCloud>& views, const DensityOptions& options,
                               const Progress& progress) {
    Stopwatch watch;
    options.check();
    Report report;
    report["method"] = "density";
    report["mark"] = options.mark;

    // Gather all views in the world frame.
    std::vector<detail::Gathered> gathered(views.size());
    std::vector<Eigen::Vector3d> world;
    std::vector<Eigen::Matrix3d> frame_rotation(views.size(), Eigen::Matrix3d::Identity());
    bool have_cameras = true;
    for (std::size_t v = 0; v < views.size(); ++v) {
        PointCloud& view = views[v];
        gathered[v] = detail::gather(view);
        if (gathered[v].xyz.empty()) continue;
        const bool posed = view.view.world_from_sensor.has_value();
        if (!posed || !view.view.intrinsics) have_cameras = false;
        Pose world_from_frame = Pose::Identity();
        if (view.view.frame == ViewFrame::kSensor) {
            RGBD_CHECK(posed || views.size() == 1,
                       detail::view_name(view) +
                           ": --density merges views in the world frame and needs "
                           "world_from_sensor (run rgbd-align first)");
            if (posed) world_from_frame = *view.view.world_from_sensor;
        }
        frame_rotation[v] = world_from_frame.linear();
        for (const auto& p : gathered[v].xyz) world.push_back(world_from_frame * p);
    }
    const std::size_t n = world.size();
    report["input_points"] = n;
    DensityReference reference = options.reference;
    if (reference == DensityReference::kAuto)
        reference = have_cameras ? DensityReference::kSensors : DensityReference::kLocal;
    if (reference == DensityReference::kSensors)
        for (const auto& view : views)
            RGBD_CHECK(view.empty() || (view.view.world_from_sensor && view.view.intrinsics),
                       detail::view_name(view) +
                           ": the sensors' density reference needs the view's intrinsics and "
                           "world_from_sensor pose");
    report["reference"] = reference == DensityReference::kSensors ? "sensors" : "local";
    const std::size_t k = std::min<std::size_t>(std::size_t(options.k), n > 0 ? n - 1 : 0);
    if (n < 3 || k < 2) {
        report["removed"] = 0;
        report["time_s"] = watch.seconds();
        return report;
    }
    if (!report_progress(progress, 0.0)) return detail::cancelled(report, watch);
    const double theta_max = options.theta_max_deg * std::numbers::pi / 180.0;
    const double cos_min = std::cos(theta_max);
    const double tan_max = std::tan(theta_max);

    // Depth maps of the views (sensors reference only).
    std::vector<Camera> cameras;
    if (reference == DensityReference::kSensors) {
        cameras.resize(views.size());
        for (std::size_t v = 0; v < views.size(); ++v) {
            if (gathered[v].xyz.empty()) continue;
            Camera& c = cameras[v];
            c.intrinsics = *views[v].view.intrinsics;
            c.sensor_from_world = views[v].view.world_from_sensor->inverse();
            c.focal = 0.5 * (c.intrinsics.fx + c.intrinsics.fy);
            c.depth.assign(std::size_t(c.intrinsics.width) * c.intrinsics.height,
                           std::numeric_limits<float>::infinity());
        }
        tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
            Camera& c = cameras[v];
            if (c.depth.empty()) return;
            const Pose frame_to_sensor =
                views[v].view.frame == ViewFrame::kWorld ? c.sensor_from_world : Pose::Identity();
            for (const auto& p : gathered[v].xyz) {
                const Eigen::Vector3d q = frame_to_sensor * p;
                if (q.z() <= 0.0) continue;
                const Eigen::Vector2d uv = c.intrinsics.project(q);
                if (!c.intrinsics.contains(uv)) continue;
                const std::size_t px = std::size_t(std::lround(uv.y())) * c.intrinsics.width +
                                       std::size_t(std::lround(uv.x()));
                c.depth[px] = std::min(c.depth[px], float(q.z()));
            }
        });
    }

    // One view's spacing ŝ (median over the views with >= 10 points): the merged cloud's
    // spacing shrinks with every interleaved view. It scales the neighbourhood of the measured
    // density and the link of the cluster pass.
    std::vector<double> spacings;
    for (std::size_t v = 0, first = 0; v < gathered.size(); ++v) {
        const std::size_t count = gathered[v].xyz.size();
        if (count >= 10)
            spacings.push_back(sampling::robust_spacing(
                std::vector<Eigen::Vector3d>(world.begin() + std::ptrdiff_t(first),
                                             world.begin() + std::ptrdiff_t(first + count)),
                2000, options.seed));
        first += count;
    }
    if (spacings.empty()) spacings.push_back(sampling::robust_spacing(world, 10000, options.seed));
    const double spacing = detail::median_of(spacings);
    report["spacing_m"] = spacing;

    std::vector<double> measured(n), expected(n, 0.0);
    if (reference == DensityReference::kSensors) {
        // Measured density: the points within r of p_i, r chosen so that a frontal surface seen
        // by one sensor puts about k points there (pi r^2 = k ŝ^2): rho_i = (count - 1) /
        // (pi r^2). Counted cell by cell on a grid of side r (27 cells per point, no tree).
        // Normals for the incidence term: the views' own (rgbd-align writes them, estimated
        // per view) or the PCA of the same neighbourhood.
        bool view_normals = true;
        for (std::size_t v = 0; v < views.size(); ++v)
            if (!gathered[v].xyz.empty() && !views[v].points.has_normal_map()) view_normals = false;
        std::vector<Eigen::Vector3d> normal(n);
        if (view_normals)
            for (std::size_t v = 0, i = 0; v < views.size(); ++v) {
                const Eigen::Matrix3d rot = frame_rotation[v];
                for (const PointSet::Index idx : gathered[v].ids)
                    normal[i++] = rot * to_eigen(views[v].points.normal(idx));
            }
        const double radius = std::sqrt(double(options.k) / std::numbers::pi) * spacing;
        const double r2 = radius * radius, area = std::numbers::pi * r2;
        report["radius_m"] = radius;
        // Density (and PCA normal) of point i from its neighbourhood's count and moments
        // (offsets d = q - p_i, the point itself included).
        const auto finish = [&](std::size_t i, std::size_t count, const Eigen::Vector3d& sum,
                                const Eigen::Matrix3d& outer) {
            measured[i] = double(count - 1) / area;
            if (view_normals) return;
            const Eigen::Vector3d mean = sum / double(count);
            const Eigen::Matrix3d cov = outer / double(count) - mean * mean.transpose();
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
            eig.computeDirect(cov);
            normal[i] = eig.eigenvectors().col(0);
        };
        CellGrid grid;
        if (grid.build(world, radius)) {
            std::vector<Eigen::Vector3d> sorted(n);
            for (std::size_t a = 0; a < n; ++a) sorted[a] = world[grid.keyed[a].second];
            tbb::parallel_for(
                tbb::blocked_range<std::size_t>(0, grid.cells(), 64),
                [&](const tbb::blocked_range<std::size_t>& r) {
                    std::pair<std::uint32_t, std::uint32_t> ranges[27];
                    for (std::size_t ca = r.begin(); ca != r.end(); ++ca) {
                        const std::uint64_t key = grid.keys[ca];
                        const std::uint64_t x = key >> 42, y = (key >> 21) & kKeyMask,
                                            z = key & kKeyMask;
                        int nr = 0;
                        for (std::uint64_t cx = x - 1; cx <= x + 1; ++cx)
                            for (std::uint64_t cy = y - 1; cy <= y + 1; ++cy) {
                                const std::uint64_t lo = key_of(cx, cy, z - 1);
                                const std::uint64_t hi = key_of(cx, cy, z + 1);
                                auto it = std::lower_bound(grid.keys.begin(), grid.keys.end(), lo);
                                for (; it != grid.keys.end() && *it <= hi; ++it) {
                                    const std::size_t cb = std::size_t(it - grid.keys.begin());
                                    ranges[nr++] = {grid.start[cb], grid.start[cb + 1]};
                                }
                            }
                        for (std::uint32_t a = grid.start[ca]; a < grid.start[ca + 1]; ++a) {
                            const Eigen::Vector3d p = sorted[a];
                            std::size_t count = 0;
                            Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                            Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
                            for (int q = 0; q < nr; ++q)
                                for (std::uint32_t b = ranges[q].first; b < ranges[q].second; ++b) {
                                    const Eigen::Vector3d d = sorted[b] - p;
                                    if (d.squaredNorm() > r2) continue;
                                    ++count;
                                    if (view_normals) continue;
                                    sum += d;
                                    outer += d * d.transpose();
                                }
                            finish(grid.keyed[a].second, count, sum, outer);
                        }
                    }
                });
        } else {  // extent too large for the grid: the same neighbourhoods from a kd-tree
            const internal::KdTree tree(world);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256),
                              [&](const tbb::blocked_range<std::size_t>& r) {
                                  std::vector<std::pair<std::uint32_t, double>> found;
                                  for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                      tree.radius(world[i], radius, found, /*sorted=*/false);
                                      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                                      Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
                                      for (const auto& f : found) {
                                          const Eigen::Vector3d d = world[f.first] - world[i];
                                          sum += d;
                                          outer += d * d.transpose();
                                      }
                                      finish(i, found.size(), sum, outer);
                                  }
                              });
        }
        if (!report_progress(progress, 0.3)) return detail::cancelled(report, watch);
        // Expected density: what the sensors that see p_i should have produced there.
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, n, 256),
            [&](const tbb::blocked_range<std::size_t>& r) {
                for (std::size_t i = r.begin(); i != r.end(); ++i) {
                    const Eigen::Vector3d nrm = normal[i].normalized();
                    double sum = 0.0;
                    for (const Camera& c : cameras) {
                        if (c.depth.empty()) continue;
                        const Eigen::Vector3d q = c.sensor_from_world * world[i];
                        if (q.z() <= 0.0) continue;
                        const Eigen::Vector2d uv = c.intrinsics.project(q);
                        if (!c.intrinsics.contains(uv)) continue;
                        const int col = int(std::lround(uv.x())), row = int(std::lround(uv.y()));
                        // max_depth_step_m() with tan(theta_max) hoisted out of the loop.
                        const double tol = q.z() / c.focal * tan_max +
                                           3.0 * sigma_z_m(options.noise_model, q.z(), 0.0);
                        bool any = false, seen = false;
                        double nearest = std::numeric_limits<double>::infinity();
                        for (int dr = -1; dr <= 1; ++dr)
                            for (int dc = -1; dc <= 1; ++dc) {
                                const int rr = row + dr, cc = col + dc;
                                if (rr < 0 || cc < 0 || rr >= c.intrinsics.height ||
                                    cc >= c.intrinsics.width)
                                    continue;
                                const double d = c.depth[std::size_t(rr) * c.intrinsics.width + cc];
                                if (!std::isfinite(d)) continue;
                                any = true;
                                nearest = std::min(nearest, d);
                                if (std::abs(d - q.z()) <= tol) seen = true;
                            }
                        // Occluded: behind v's surface, so v could not have measured it.
                        if (any && !seen && q.z() > nearest + tol) continue;
                        // Ray from camera v to the point, in the world frame.
                        const Eigen::Vector3d ray =
                            c.sensor_from_world.linear().transpose() * q.normalized();
                        const double cos_theta = std::max(cos_min, std::abs(nrm.dot(ray)));
                        const double s_d = q.z() / c.focal;
                        sum += cos_theta / (s_d * s_d);
                    }
                    expected[i] = sum;
                }
            });
    } else {
        // Local reference (no cameras): measured rho_i = k / (pi d_k^2) from the k nearest
        // other points, expected = the median measured density of the k_ref nearest.
        const internal::KdTree tree(world);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              std::vector<std::uint32_t> ids(k + 1);
                              std::vector<double> sq(k + 1);
                              for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                  const std::size_t found =
                                      tree.knn(world[i], k + 1, ids.data(), sq.data());
                                  const double dk2 = std::max(sq[found - 1], 1e-18);
                                  measured[i] = double(found - 1) / (std::numbers::pi * dk2);
                              }
                          });
        if (!report_progress(progress, 0.3)) return detail::cancelled(report, watch);
        const std::size_t k_ref = std::min<std::size_t>(std::size_t(options.k_ref), n - 1);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              std::vector<std::uint32_t> ids(k_ref + 1);
                              std::vector<double> sq(k_ref + 1);
                              std::vector<double> dens(k_ref + 1);
                              for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                  const std::size_t found =
                                      tree.knn(world[i], k_ref + 1, ids.data(), sq.data());
                                  dens.resize(found);
                                  for (std::size_t j = 0; j < found; ++j)
                                      dens[j] = measured[ids[j]];
                                  expected[i] = detail::median_of(dens);
                              }
                          });
    }
    if (!report_progress(progress, 0.5)) return detail::cancelled(report, watch);

    const double beta = reference == DensityReference::kSensors ? options.beta : options.beta_local;
    std::vector<std::uint8_t> outlier(n, 0);
    std::size_t density_removed = 0;
    for (std::size_t i = 0; i < n; ++i)
        if (measured[i] < beta * expected[i]) {
            outlier[i] = 1;
            ++density_removed;
        }
    report["density"] = density_removed;

    // Cluster pass over the survivors.
    std::size_t cluster_removed = 0, clusters = 0;
    if (options.cluster_spacing > 0.0) {
        std::vector<std::uint32_t> alive;
        for (std::size_t i = 0; i < n; ++i)
            if (!outlier[i]) alive.push_back(static_cast<std::uint32_t>(i));
        const std::size_t m = alive.size();
        if (m >= 2) {
            std::vector<Eigen::Vector3d> pts(m);
            for (std::size_t a = 0; a < m; ++a) pts[a] = world[alive[a]];
            const double eps = options.cluster_spacing * spacing;
            report["cluster_eps_m"] = eps;
            // Component label of every survivor; equal labels = one component.
            std::vector<std::uint32_t> label;
            if (!eps_components(pts, eps, label)) {
                // Grid too fine for the extent: radius search per point instead.
                const internal::KdTree alive_tree(pts);
                constexpr std::size_t kBlock = 1024;
                const std::size_t blocks = (m + kBlock - 1) / kBlock;
                std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> edges(blocks);
                tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
                    std::vector<std::pair<std::uint32_t, double>> found;
                    for (std::size_t a = b * kBlock; a < std::min(m, (b + 1) * kBlock); ++a) {
                        alive_tree.radius(pts[a], eps, found, /*sorted=*/false);
                        for (const auto& f : found)
                            if (f.first > a) edges[b].emplace_back(std::uint32_t(a), f.first);
                    }
                });
                detail::DisjointSets sets(m);
                for (const auto& block : edges)
                    for (const auto& e : block) sets.unite(e.first, e.second);
                label.resize(m);
                for (std::size_t a = 0; a < m; ++a) label[a] = sets.find(std::uint32_t(a));
            }
            // Per component: size and first member (the tie-break of the largest).
            constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
            std::vector<std::uint32_t> size(m, 0), first(m, kNone);
            for (std::size_t a = 0; a < m; ++a) {
                ++size[label[a]];
                if (first[label[a]] == kNone) first[label[a]] = std::uint32_t(a);
            }
            std::uint32_t largest = label[0];
            for (std::size_t c = 0; c < m; ++c) {
                if (size[c] == 0) continue;
                ++clusters;
                if (size[c] > size[largest] ||
                    (size[c] == size[largest] && first[c] < first[largest]))
                    largest = std::uint32_t(c);
            }
            const double keep = options.min_cluster_fraction * double(m);
            for (std::size_t a = 0; a < m; ++a) {
                const std::uint32_t root = label[a];
                if (root != largest && double(size[root]) < keep) {
                    outlier[alive[a]] = 1;
                    ++cluster_removed;
                }
            }
        }
    }
    report["cluster"] = cluster_removed;
    report["clusters"] = clusters;

    // Apply per view.
    std::size_t total = 0, offset = 0;
    Report per_view = Report::array();
    for (std::size_t v = 0; v < views.size(); ++v) {
        const std::size_t count = gathered[v].xyz.size();
        std::vector<std::uint8_t> flags(outlier.begin() + std::ptrdiff_t(offset),
                                        outlier.begin() + std::ptrdiff_t(offset + count));
        offset += count;
        const std::size_t removed = detail::apply(views[v], gathered[v], flags, options.mark);
        total += removed;
        per_view.push_back({{"view", views[v].view.id},
                            {"input_points", count},
                            {options.mark ? "marked" : "removed", removed}});
    }
    report["views"] = per_view;
    report[options.mark ? "marked" : "removed"] = total;
    if (options.mark) report["removed"] = 0;
    report_progress(progress, 1.0);
    report["time_s"] = watch.seconds();
    return report;
}

}  // namespace rgbd::denoise
