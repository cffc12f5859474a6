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
bool eps_components(const std::vector<Eigen::Vector3d>& pts, double eps,
                    std::vector<std::uint32_t>& label) {
    const std::size_t m = pts.size();
    const double cell = eps / std::sqrt(3.0) * (1.0 - 1e-9);
    if (!(cell > 0.0) || m == 0) return false;
    Eigen::Vector3d lo = pts[0], hi = pts[0];
    for (const auto& p : pts) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    constexpr double kMaxCells = double(1 << 21) - 8.0;
    if (((hi - lo) / cell).maxCoeff() >= kMaxCells) return false;
    // Cell coordinates offset by 2 so that neighbour offsets -2..2 never underflow.
    const auto key_of = [](std::uint64_t x, std::uint64_t y, std::uint64_t z) {
        return (x << 42) | (y << 21) | z;
    };
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(m);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, m, 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t a = r.begin(); a != r.end(); ++a) {
                              const Eigen::Vector3d c = (pts[a] - lo) / cell;
                              keyed[a] = {key_of(std::uint64_t(c.x()) + 2, std::uint64_t(c.y()) + 2,
                                                 std::uint64_t(c.z()) + 2),
                                          std::uint32_t(a)};
                          }
                      });
    std::sort(keyed.begin(), keyed.end());
    // Cells: unique keys and the range of their points in `keyed`.
    std::vector<std::uint64_t> keys;
    std::vector<std::uint32_t> start;
    for (std::size_t a = 0; a < m; ++a)
        if (a == 0 || keyed[a].first != keyed[a - 1].first) {
            keys.push_back(keyed[a].first);
            start.push_back(std::uint32_t(a));
        }
    const std::size_t cells = keys.size();
    start.push_back(std::uint32_t(m));
    const double eps2 = eps * eps;
    detail::DisjointSets sets(cells);
    const auto linked = [&](std::size_t ca, std::size_t cb) {
        for (std::uint32_t i = start[ca]; i < start[ca + 1]; ++i)
            for (std::uint32_t j = start[cb]; j < start[cb + 1]; ++j)
                if ((pts[keyed[i].second] - pts[keyed[j].second]).squaredNorm() <= eps2)
                    return true;
        return false;
    };
    constexpr std::uint64_t kMask = (std::uint64_t(1) << 21) - 1;
    for (std::size_t ca = 0; ca < cells; ++ca) {
        const std::uint64_t x = keys[ca] >> 42, y = (keys[ca] >> 21) & kMask, z = keys[ca] & kMask;
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
    std::vector<std::uint32_t> owner;  // view position of each merged point
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
        for (const auto& p : gathered[v].xyz) {
            world.push_back(world_from_frame * p);
            owner.push_back(static_cast<std::uint32_t>(v));
        }
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

    // Measured and expected density per point.
    const internal::KdTree tree(world);
    const std::size_t k_ref = std::min<std::size_t>(std::size_t(options.k_ref), n - 1);
    std::vector<double> measured(n), expected(n, 0.0);
    // Squared distance to the nearest other point of the same view when it is among the k
    // neighbours (-1 otherwise): the per-view spacing of the cluster pass without a tree per view.
    std::vector<double> own_sq(n, -1.0);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 256), [&](const tbb::blocked_range<std::size_t>& r) {
            std::vector<std::uint32_t> ids(k + 1);
            std::vector<double> sq(k + 1);
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const std::size_t found = tree.knn(world[i], k + 1, ids.data(), sq.data());
                const double dk2 = std::max(sq[found - 1], 1e-18);
                measured[i] = double(found - 1) / (std::numbers::pi * dk2);
                for (std::size_t j = 0; j < found; ++j)  // sorted by distance
                    if (ids[j] != i && owner[ids[j]] == owner[i]) {
                        own_sq[i] = sq[j];
                        break;
                    }
                if (reference != DensityReference::kSensors) continue;
                Eigen::Vector3d mean = Eigen::Vector3d::Zero();
                for (std::size_t j = 0; j < found; ++j) mean += world[ids[j]];
                mean /= double(found);
                Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
                for (std::size_t j = 0; j < found; ++j) {
                    const Eigen::Vector3d d = world[ids[j]] - mean;
                    cov += d * d.transpose();
                }
                const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
                const Eigen::Vector3d normal = eig.eigenvectors().col(0);
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
                    const double cos_theta = std::max(cos_min, std::abs(normal.dot(ray)));
                    const double s_d = q.z() / c.focal;
                    sum += cos_theta / (s_d * s_d);
                }
                expected[i] = sum;
            }
        });
    if (!report_progress(progress, 0.5)) return detail::cancelled(report, watch);
    if (reference == DensityReference::kLocal) {
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

    std::vector<std::uint8_t> outlier(n, 0);
    std::size_t density_removed = 0;
    for (std::size_t i = 0; i < n; ++i)
        if (measured[i] < options.beta * expected[i]) {
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
            // The spacing of one view (median over the views): the merged cloud's spacing
            // shrinks with every interleaved view and would cut the surface into pieces.
            // robust_spacing() of every view with >= 10 points, from own_sq; a point whose
            // nearest same-view point was not among its k neighbours is searched in a tree of
            // its view (built only for such views).
            std::vector<double> spacings;
            for (std::size_t v = 0, first = 0; v < gathered.size(); ++v) {
                const std::size_t count = gathered[v].xyz.size();
                if (count >= 10) {
                    const std::vector<std::uint32_t> sample =
                        internal::spacing_sample(count, 10000, options.seed);
                    std::vector<double> dist(sample.size());
                    std::vector<std::size_t> misses;
                    for (std::size_t q = 0; q < sample.size(); ++q) {
                        const double d2 = own_sq[first + sample[q]];
                        if (d2 < 0.0)
                            misses.push_back(q);
                        else
                            dist[q] = std::sqrt(d2);
                    }
                    if (!misses.empty()) {
                        const std::vector<Eigen::Vector3d> slice(
                            world.begin() + std::ptrdiff_t(first),
                            world.begin() + std::ptrdiff_t(first + count));
                        const internal::KdTree view_tree(slice);
                        for (const std::size_t q : misses) {
                            std::uint32_t idx[2];
                            double sq2[2];
                            const std::size_t found = view_tree.knn(slice[sample[q]], 2, idx, sq2);
                            double d2 = 0.0;
                            if (found == 2) d2 = idx[0] == sample[q] ? sq2[1] : sq2[0];
                            dist[q] = std::sqrt(d2);
                        }
                    }
                    spacings.push_back(internal::spacing_median(dist));
                }
                first += count;
            }
            if (spacings.empty())
                spacings.push_back(sampling::robust_spacing(pts, 10000, options.seed));
            const double spacing = detail::median_of(spacings);
            const double eps = options.cluster_spacing * spacing;
            report["spacing_m"] = spacing;
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
