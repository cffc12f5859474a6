#include "algorithms/denoise/density_outliers.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/denoise/density_camera.hpp"
#include "algorithms/denoise/density_clusters.hpp"
#include "algorithms/denoise/density_counting.hpp"
#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/internal/spacing_sample.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "toolkit/error.hpp"
#include "toolkit/order_statistics.hpp"

namespace rgbd::denoise {

void DensityOptions::check() const {
    check_range("density outliers: theta_max", theta_max_deg, Range::open_closed(0.0, 89.0),
                "degrees");
    check_range("density outliers: k", k, Range::closed(2, 1000));
    check_range("density outliers: k_ref", k_ref, Range::closed(1, 10000));
    check_range("density outliers: beta", beta, Range::closed(0.0, 100.0));
    check_range("density outliers: beta_local", beta_local, Range::closed(0.0, 100.0));
    check_range("density outliers: consensus_ratio", consensus_ratio, Range::closed(0.0, 1.0));
    check_range("density outliers: consensus_sigmas", consensus_sigmas,
                Range::open_closed(0.0, 1000.0));
    check_range("density outliers: consensus_radius", consensus_radius,
                Range::open_closed(0.0, 2.0));
    check_range("density outliers: cluster_spacing", cluster_spacing, Range::closed(0.0, 1000.0));
    check_range("density outliers: min_cluster_fraction", min_cluster_fraction,
                Range::closed(0.0, 1.0));
}

namespace {

using detail::Camera;
using detail::camera_density;
using detail::surely_occluded;

/// The live points of all views, in the world frame, concatenated in view order.
struct WorldPoints {
    std::vector<detail::Gathered> gathered;       ///< each view's live points in its own frame
    std::vector<Eigen::Matrix3d> frame_rotation;  ///< world_from_frame's rotation per view
    std::vector<std::size_t> offset;  ///< view v's points: world[offset[v], offset[v + 1])
    std::vector<Eigen::Vector3d> world;
    std::vector<std::uint32_t> view_of;  ///< view index of every point of `world`
    bool have_cameras = true;            ///< every non-empty view has intrinsics and a pose
    /// The point each point was made from (find_parents()): itself for a measured point, the
    /// measured point of its view that a super-resolved point was made from; empty when every
    /// point is its own parent.
    std::vector<std::uint32_t> parent;
    /// Whether point i is its own parent (a measured point).
    bool own_parent(std::size_t i) const { return parent.empty() || parent[i] == i; }
};

/// The parents of the points of view v (all.parent, its slice): a measured point (not flagged
/// synthetic) is its own; a super-resolved point's is the measured point with its pixel (it
/// carries its parent's pixel), else the measured point of the view nearest to it. A view
/// without measured points is its own parents. Returns how many points have another parent.
std::size_t find_view_parents(const PointCloud& view, WorldPoints& all, std::size_t v) {
    const std::size_t first = all.offset[v], n = all.offset[v + 1] - first;
    for (std::size_t a = 0; a < n; ++a) all.parent[first + a] = std::uint32_t(first + a);
    const auto synthetic = view.flag(prop::kSynthetic);
    if (!synthetic) return 0;
    const auto& ids = all.gathered[v].ids;
    const auto& xyz = all.gathered[v].xyz;
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    const auto pixel = view.pixel_map();
    const std::size_t cells = std::size_t(std::max(view.view.grid_width, 0)) *
                              std::size_t(std::max(view.view.grid_height, 0));
    std::vector<std::uint32_t> at_pixel;  // the measured point of every pixel of the view's grid
    std::vector<Eigen::Vector3d> measured_xyz;
    std::vector<std::uint32_t> measured_at;
    if (pixel && cells > 0) at_pixel.assign(cells, kNone);
    for (std::size_t a = 0; a < n; ++a) {
        if ((*synthetic)[ids[a]]) continue;
        measured_xyz.push_back(xyz[a]);
        measured_at.push_back(static_cast<std::uint32_t>(a));
        if (!at_pixel.empty())
            if (const std::uint32_t px = (*pixel)[ids[a]]; px < cells)
                at_pixel[px] = static_cast<std::uint32_t>(a);
    }
    if (measured_xyz.empty()) return 0;
    std::unique_ptr<internal::KdTree> tree;  // built for the first point without a parent pixel
    std::size_t followers = 0;
    for (std::size_t a = 0; a < n; ++a) {
        if (!(*synthetic)[ids[a]]) continue;
        std::uint32_t from = kNone;
        if (!at_pixel.empty())
            if (const std::uint32_t px = (*pixel)[ids[a]]; px < cells) from = at_pixel[px];
        if (from == kNone) {
            if (!tree) tree = std::make_unique<internal::KdTree>(measured_xyz);
            std::uint32_t nearest = 0;
            double sq = 0.0;
            if (tree->nearest(xyz[a], nearest, sq)) from = measured_at[nearest];
        }
        all.parent[first + a] = std::uint32_t(first + from);
        ++followers;
    }
    return followers;
}

/// find_view_parents() for every view (in parallel); all.parent stays empty when every point is
/// its own parent. Returns how many points have another parent.
std::size_t find_parents(const std::vector<PointCloud>& views, WorldPoints& all) {
    all.parent.resize(all.world.size());
    std::vector<std::size_t> followers(views.size(), 0);
    tbb::parallel_for(std::size_t(0), views.size(),
                      [&](std::size_t v) { followers[v] = find_view_parents(views[v], all, v); });
    std::size_t total = 0;
    for (const std::size_t f : followers) total += f;
    if (total == 0) all.parent.clear();
    return total;
}

/// Gathers all views in the world frame: each view's points in parallel (an error names the
/// first offending view, as a sequential pass would), then placed at their offsets. InputError
/// for a sensor-frame view without a pose among several views.
WorldPoints gather_in_world(const std::vector<PointCloud>& views) {
    WorldPoints all;
    all.gathered.resize(views.size());
    std::vector<std::exception_ptr> failed(views.size());
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
        try {
            all.gathered[v] = detail::gather(views[v]);
        } catch (...) {
            failed[v] = std::current_exception();
        }
    });
    all.frame_rotation.assign(views.size(), Eigen::Matrix3d::Identity());
    std::vector<Pose> world_from_frame(views.size(), Pose::Identity());
    all.offset.assign(views.size() + 1, 0);
    for (std::size_t v = 0; v < views.size(); ++v) {
        if (failed[v]) std::rethrow_exception(failed[v]);
        all.offset[v + 1] = all.offset[v] + all.gathered[v].xyz.size();
        if (all.gathered[v].xyz.empty()) continue;
        const PointCloud& view = views[v];
        const bool posed = view.view.world_from_sensor.has_value();
        if (!posed || !view.view.intrinsics) all.have_cameras = false;
        if (view.view.frame == ViewFrame::kSensor) {
            RGBD_CHECK(posed || views.size() == 1,
                       detail::view_name(view) +
                           ": --density merges views in the world frame and needs "
                           "world_from_sensor (run rgbd-align first)");
            if (posed) world_from_frame[v] = *view.view.world_from_sensor;
        }
        all.frame_rotation[v] = world_from_frame[v].linear();
    }
    all.world.resize(all.offset.back());
    all.view_of.resize(all.offset.back());
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
        for (std::size_t a = 0; a < all.gathered[v].xyz.size(); ++a) {
            all.world[all.offset[v] + a] = world_from_frame[v] * all.gathered[v].xyz[a];
            all.view_of[all.offset[v] + a] = std::uint32_t(v);
        }
    });
    return all;
}

/// The density reference to use: `requested`, or for kAuto the sensors when every view has a
/// camera. InputError naming the view when the sensors reference lacks a view's camera.
DensityReference choose_reference(const std::vector<PointCloud>& views, DensityReference requested,
                                  bool have_cameras) {
    DensityReference reference = requested;
    if (reference == DensityReference::kAuto)
        reference = have_cameras ? DensityReference::kSensors : DensityReference::kLocal;
    if (reference == DensityReference::kSensors)
        for (const auto& view : views)
            RGBD_CHECK(view.empty() || (view.view.world_from_sensor && view.view.intrinsics),
                       detail::view_name(view) +
                           ": the sensors' density reference needs the view's intrinsics and "
                           "world_from_sensor pose");
    return reference;
}

/// The depth map of view v's points in its own camera (nearest return per pixel) over their
/// bounding box; left empty (bw = bh = 0) when no point projects into the image.
void build_depth_map(Camera& c, const PointCloud& view, const detail::Gathered& gathered) {
    const Pose frame_to_sensor =
        view.view.frame == ViewFrame::kWorld ? c.sensor_from_world : Pose::Identity();
    struct Hit {
        int col, row;
        float z;
    };
    std::vector<Hit> hits;
    hits.reserve(gathered.xyz.size());
    int lo_x = std::numeric_limits<int>::max(), lo_y = lo_x, hi_x = -1, hi_y = -1;
    for (const auto& p : gathered.xyz) {
        const Eigen::Vector3d q = frame_to_sensor * p;
        if (q.z() <= 0.0) continue;
        const Eigen::Vector2d uv = c.intrinsics.project(q);
        if (!c.intrinsics.contains(uv)) continue;
        const int col = int(std::lround(uv.x())), row = int(std::lround(uv.y()));
        hits.push_back({col, row, float(q.z())});
        lo_x = std::min(lo_x, col);
        hi_x = std::max(hi_x, col);
        lo_y = std::min(lo_y, row);
        hi_y = std::max(hi_y, row);
    }
    if (hits.empty()) return;  // bw = bh = 0: no return anywhere
    c.x0 = lo_x;
    c.y0 = lo_y;
    c.bw = hi_x - lo_x + 1;
    c.bh = hi_y - lo_y + 1;
    c.depth.assign(std::size_t(c.bw) * std::size_t(c.bh), std::numeric_limits<float>::infinity());
    for (const Hit& hit : hits) {
        float& d = c.depth[std::size_t(hit.row - c.y0) * c.bw + std::size_t(hit.col - c.x0)];
        d = std::min(d, hit.z);
    }
}

/// The cameras of the views (sensors reference): pose, intrinsics and depth map of every view
/// with points; inactive for an empty view.
std::vector<Camera> view_cameras(const std::vector<PointCloud>& views, const WorldPoints& all) {
    std::vector<Camera> cameras(views.size());
    for (std::size_t v = 0; v < views.size(); ++v) {
        if (all.gathered[v].xyz.empty()) continue;
        Camera& c = cameras[v];
        c.set(*views[v].view.world_from_sensor, *views[v].view.intrinsics);
        c.active = true;
    }
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
        if (cameras[v].active) build_depth_map(cameras[v], views[v], all.gathered[v]);
    });
    return cameras;
}

/// One view's spacing ŝ: the median robust spacing over the views with >= 10 points (the
/// merged cloud's spacing shrinks with every interleaved view), or the merged cloud's when no
/// view has that many. It scales the neighbourhood of the measured density and, of the measured
/// points only (`parents_only`: the points that are their own parents), the link of the
/// cluster pass.
double one_view_spacing(const WorldPoints& all, std::uint64_t seed, bool parents_only = false) {
    // The views' own point sets (frame-independent spacing), in parallel.
    std::vector<double> view_spacing(all.gathered.size(), -1.0);
    tbb::parallel_for(std::size_t(0), all.gathered.size(), [&](std::size_t v) {
        std::vector<Eigen::Vector3d> own;
        if (parents_only && !all.parent.empty())
            for (std::size_t a = 0; a < all.gathered[v].xyz.size(); ++a)
                if (all.own_parent(all.offset[v] + a)) own.push_back(all.gathered[v].xyz[a]);
        const auto& xyz = parents_only && !all.parent.empty() ? own : all.gathered[v].xyz;
        if (xyz.size() >= 10) view_spacing[v] = sampling::robust_spacing(xyz, 2000, seed);
    });
    std::vector<double> spacings;
    for (const double s : view_spacing)
        if (s >= 0.0) spacings.push_back(s);
    if (spacings.empty()) spacings.push_back(sampling::robust_spacing(all.world, 10000, seed));
    return lower_median(spacings);
}

/// The sensors reference's neighbourhoods: the normals, the counting radius and its grid (kept
/// for the consensus test; `gridded` false when the extent needed the kd-tree instead).
struct Neighbourhoods {
    std::vector<Eigen::Vector3d> normal;
    double radius = 0.0;
    internal::CellGrid grid;
    bool gridded = false;
};

/// Measured density, sensors reference: the points within r of p_i, r chosen so that a frontal
/// surface seen by one sensor puts about k points there (pi r^2 = k ŝ^2): rho_i = (count - 1) /
/// (pi r^2), into `measured`. Normals for the incidence term: the views' own (rgbd-align writes
/// them, estimated per view) or the PCA of the same neighbourhood. Returns the neighbourhoods.
void measure_sensor_density(const std::vector<PointCloud>& views, const WorldPoints& all, int k,
                            double spacing, std::vector<double>& measured, Neighbourhoods& hood) {
    const std::size_t n = all.world.size();
    bool view_normals = true;
    for (std::size_t v = 0; v < views.size(); ++v)
        if (!all.gathered[v].xyz.empty() && !views[v].points.has_normal_map()) view_normals = false;
    hood.normal.resize(n);
    if (view_normals)
        for (std::size_t v = 0, i = 0; v < views.size(); ++v) {
            const Eigen::Matrix3d rot = all.frame_rotation[v];
            for (PointSet::Index idx : all.gathered[v].ids)
                hood.normal[i++] = rot * to_eigen(views[v].points.normal(idx));
        }
    hood.radius = std::sqrt(double(k) / std::numbers::pi) * spacing;
    const double r2 = hood.radius * hood.radius, area = std::numbers::pi * r2;
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
        hood.normal[i] = eig.eigenvectors().col(0);
    };
    hood.gridded = hood.grid.build(all.world, hood.radius);
    if (hood.gridded)
        detail::count_on_grid(hood.grid, all.world, r2, view_normals, finish);
    else
        detail::count_with_tree(all.world, hood.radius, finish);
}

/// Expected density, sensors reference: what the sensors that see p_i should have produced
/// there, the sum of camera_density() over the cameras (in camera order), into `expected`. On
/// the counting grid, cell by cell: the cameras that surely find the whole cell occluded
/// (surely_occluded(): about half of them for an object seen all round) are left out of its
/// points' sums, which changes no sum (those cameras add nothing) and saves their projections.
void expect_sensor_density(const std::vector<Camera>& cameras, const WorldPoints& all,
                           const Neighbourhoods& hood, NoiseModel noise_model, double tan_max,
                           std::vector<double>& expected) {
    const std::vector<Eigen::Vector3d>& normal = hood.normal;
    std::vector<std::uint32_t> active;
    for (std::size_t v = 0; v < cameras.size(); ++v)
        if (cameras[v].active) active.push_back(std::uint32_t(v));
    const auto expect = [&](std::size_t i, const std::vector<std::uint32_t>& seeing) {
        if (!all.own_parent(i)) return;  // its parent's, below
        const Eigen::Vector3d nrm = normal[i].normalized();
        double sum = 0.0;
        for (const std::uint32_t v : seeing)
            if (const auto add =
                    camera_density(cameras[v], all.world[i], nrm, noise_model, tan_max))
                sum += *add;
        expected[i] = sum;
    };
    // The culling pays when cells hold many points (many views overlap: 26 a cell on the
    // 50-view person, 35% of the pairs left out on a 10-view ring at 7 a cell did not).
    constexpr std::size_t kMinPointsPerCell = 12;
    if (!hood.gridded || all.world.size() < kMinPointsPerCell * hood.grid.cells()) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, all.world.size(), 256),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t i = r.begin(); i != r.end(); ++i) expect(i, active);
                          });
        return;
    }
    const internal::CellGrid& grid = hood.grid;
    // Occlusion is coherent from a cell to the next in key order (mostly the next along a
    // column): a camera found to see a cell is not tested on the next few (the test costs about
    // as much as the sums it saves when it fails). Only the cost depends on this.
    constexpr std::uint8_t kRetestAfter = 3;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, grid.cells(), 16),
        [&](const tbb::blocked_range<std::size_t>& r) {
            std::vector<std::uint32_t> seeing;
            seeing.reserve(active.size());
            // Cells to wait before testing camera a again after it saw a cell.
            std::vector<std::uint8_t> wait(active.size(), 0);
            for (std::size_t ca = r.begin(); ca != r.end(); ++ca) {
                const std::uint32_t b0 = grid.start[ca], b1 = grid.start[ca + 1];
                Eigen::Vector3d lo = all.world[grid.point[b0]], hi = lo;
                for (std::uint32_t b = b0 + 1; b < b1; ++b) {
                    lo = lo.cwiseMin(all.world[grid.point[b]]);
                    hi = hi.cwiseMax(all.world[grid.point[b]]);
                }
                seeing.clear();
                for (std::size_t a = 0; a < active.size(); ++a) {
                    const std::uint32_t v = active[a];
                    if (wait[a] > 0) {
                        --wait[a];
                        seeing.push_back(v);
                    } else if (!surely_occluded(cameras[v], lo, hi, noise_model, tan_max)) {
                        wait[a] = kRetestAfter;
                        seeing.push_back(v);
                    }
                }
                for (std::uint32_t b = b0; b < b1; ++b) expect(grid.point[b], seeing);
            }
        });
}

/// Measured density, local reference: rho_i = k / (pi d_k^2) from the k nearest other points.
void measure_local_density(const internal::KdTree& tree, const std::vector<Eigen::Vector3d>& world,
                           std::size_t k, std::vector<double>& measured) {
    detail::for_each_knn(
        tree, world, k + 1, 256,
        [&](std::size_t i, const std::uint32_t*, const double* sq, std::size_t found) {
            const double dk2 = std::max(sq[found - 1], 1e-18);
            measured[i] = double(found - 1) / (std::numbers::pi * dk2);
        });
}

/// Expected density, local reference: the median measured density of the k_ref nearest points.
void expect_local_density(const internal::KdTree& tree, const std::vector<Eigen::Vector3d>& world,
                          const std::vector<double>& measured, std::size_t k_ref,
                          std::vector<double>& expected) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, world.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::vector<std::uint32_t> ids(k_ref + 1);
                          std::vector<double> sq(k_ref + 1);
                          std::vector<double> dens(k_ref + 1);
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const std::size_t found =
                                  tree.knn(world[i], k_ref + 1, ids.data(), sq.data());
                              dens.resize(found);
                              for (std::size_t j = 0; j < found; ++j) dens[j] = measured[ids[j]];
                              expected[i] = lower_median(dens);
                          }
                      });
}

/// The density test: flags (outlier[i] = 1) every point whose measured density is below beta
/// times its expected one; returns how many.
std::size_t flag_sparse(const std::vector<double>& measured, const std::vector<double>& expected,
                        double beta, std::vector<std::uint8_t>& outlier) {
    std::size_t removed = 0;
    for (std::size_t i = 0; i < measured.size(); ++i)
        if (measured[i] < beta * expected[i]) {
            outlier[i] = 1;
            ++removed;
        }
    return removed;
}

/// Consensus candidates: the points not yet flagged with less than consensus_ratio of their
/// expected density that their own view sees at an incidence steeper than theta_max.
std::vector<std::uint32_t> consensus_candidates(const WorldPoints& all,
                                                const std::vector<Camera>& cameras,
                                                const std::vector<Eigen::Vector3d>& normal,
                                                const std::vector<double>& measured,
                                                const std::vector<double>& expected,
                                                const std::vector<std::uint8_t>& outlier,
                                                double consensus_ratio, double theta_max) {
    const double cos_max = std::cos(theta_max);
    std::vector<std::uint32_t> candidates;
    for (std::size_t i = 0; i < all.world.size(); ++i) {
        if (outlier[i] || !(measured[i] < consensus_ratio * expected[i])) continue;
        const Camera& c = cameras[all.view_of[i]];
        const Eigen::Vector3d q = c.rotation * all.world[i] + c.translation;
        const Eigen::Vector3d ray = c.rotation.transpose() * q.normalized();
        if (std::abs(normal[i].normalized().dot(ray)) < cos_max)
            candidates.push_back(std::uint32_t(i));
    }
    return candidates;
}

/// Fewest other views' points around a consensus candidate that can judge it.
constexpr std::size_t kMinSupport = 6;

/// Whether point p (of the view whose noise is sigma at p) lies more than `sigmas` sigma off
/// the plane of `near` (at least kMinSupport offsets of the other views' points around p): a
/// PCA plane, trimmed twice to 3 sigma (stopping when too few would remain). `inlier` is a
/// reused buffer.
bool off_plane(const std::vector<Eigen::Vector3d>& near, double sigma, double sigmas,
               std::vector<std::uint8_t>& inlier) {
    inlier.assign(near.size(), 1);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero(), nrm = Eigen::Vector3d::UnitZ();
    for (int it = 0; it < 3; ++it) {
        std::size_t m = 0;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
        for (std::size_t j = 0; j < near.size(); ++j)
            if (inlier[j]) {
                ++m;
                sum += near[j];
                outer += near[j] * near[j].transpose();
            }
        mean = sum / double(m);
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
        eig.computeDirect(outer / double(m) - mean * mean.transpose());
        nrm = eig.eigenvectors().col(0);
        // Trim to 3 sigma_z of the plane; stop when too few would remain.
        std::size_t kept = 0;
        for (const auto& d : near) kept += std::abs(nrm.dot(d - mean)) < 3.0 * sigma;
        if (kept < kMinSupport) break;
        for (std::size_t j = 0; j < near.size(); ++j)
            inlier[j] = std::abs(nrm.dot(near[j] - mean)) < 3.0 * sigma;
    }
    // p is the origin of the offsets: its distance to the plane is |n . mean|.
    return std::abs(nrm.dot(mean)) > sigmas * sigma;
}

/// The consensus test over `candidates`: 1 for each candidate that lies more than
/// consensus_sigmas sigma_z (its own view's noise at its depth) off the plane of the OTHER
/// views' points within consensus_radius r (off_plane()). Neighbours from the counting grid,
/// or a kd-tree when the grid could not hold the extent.
std::vector<std::uint8_t> off_other_views(const WorldPoints& all,
                                          const std::vector<Camera>& cameras,
                                          const Neighbourhoods& hood,
                                          const std::vector<std::uint32_t>& candidates,
                                          const DensityOptions& options) {
    const double reach = options.consensus_radius * hood.radius, reach2 = reach * reach;
    std::unique_ptr<internal::KdTree> tree;  // only when the grid could not hold the extent
    if (!hood.gridded && !candidates.empty()) tree = std::make_unique<internal::KdTree>(all.world);
    std::vector<std::uint8_t> off(candidates.size(), 0);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, candidates.size(), 16),
        [&](const tbb::blocked_range<std::size_t>& r) {
            // Offsets of the other views' neighbours and their inlier flags, reused.
            std::vector<Eigen::Vector3d> near;
            std::vector<std::uint8_t> inlier;
            std::vector<std::pair<std::uint32_t, double>> found;
            near.reserve(512);
            inlier.reserve(512);
            for (std::size_t a = r.begin(); a != r.end(); ++a) {
                const std::uint32_t i = candidates[a];
                const Eigen::Vector3d& p = all.world[i];
                near.clear();
                const auto take = [&](std::uint32_t j) {
                    if (all.view_of[j] == all.view_of[i]) return;
                    const Eigen::Vector3d d = all.world[j] - p;
                    if (d.squaredNorm() <= reach2) near.push_back(d);
                };
                if (hood.gridded) {
                    // reach <= 2 r: the cells at most 2 apart on every axis.
                    const auto cell = hood.grid.cell_of(p);
                    for (std::int64_t cx = cell.x() - 2; cx <= cell.x() + 2; ++cx)
                        for (std::int64_t cy = cell.y() - 2; cy <= cell.y() + 2; ++cy) {
                            const auto [c0, c1] =
                                hood.grid.column(cx, cy, cell.z() - 2, cell.z() + 2);
                            for (std::uint32_t b = hood.grid.start[c0]; b < hood.grid.start[c1];
                                 ++b)
                                take(hood.grid.point[b]);
                        }
                } else {
                    tree->radius(p, reach, found, /*sorted=*/false);
                    for (const auto& f : found) take(f.first);
                }
                if (near.size() < kMinSupport) continue;
                const Camera& c = cameras[all.view_of[i]];
                const double sigma =
                    sigma_z_m(options.noise_model, (c.rotation * p + c.translation).z(), 0.0);
                off[a] = off_plane(near, sigma, options.consensus_sigmas, inlier);
            }
        });
    return off;
}

/// Marks or deletes the flagged points of every view (the views are independent point sets: in
/// parallel) and records the per-view counts ("views") and the total in `report`.
void apply_to_views(std::vector<PointCloud>& views, const WorldPoints& all,
                    const std::vector<std::uint8_t>& outlier, bool mark, Report& report) {
    std::vector<std::size_t> first(views.size() + 1, 0), removed(views.size(), 0);
    for (std::size_t v = 0; v < views.size(); ++v)
        first[v + 1] = first[v] + all.gathered[v].xyz.size();
    tbb::parallel_for(std::size_t(0), views.size(), [&](std::size_t v) {
        const std::vector<std::uint8_t> flags(outlier.begin() + std::ptrdiff_t(first[v]),
                                              outlier.begin() + std::ptrdiff_t(first[v + 1]));
        removed[v] = detail::apply(views[v], all.gathered[v], flags, mark);
    });
    std::size_t total = 0;
    Report per_view = Report::array();
    for (std::size_t v = 0; v < views.size(); ++v) {
        total += removed[v];
        per_view.push_back({{"view", views[v].view.id},
                            {"input_points", first[v + 1] - first[v]},
                            {mark ? "marked" : "removed", removed[v]}});
    }
    report["views"] = per_view;
    detail::record_removed(report, total, mark);
}

}  // namespace

Report remove_density_outliers(std::vector<PointCloud>& views, const DensityOptions& options,
                               const Progress& progress) {
    Stopwatch watch;
    options.check();
    Report report;
    report["method"] = "density";
    report["mark"] = options.mark;

    WorldPoints all = gather_in_world(views);
    const std::vector<Eigen::Vector3d>& world = all.world;
    const std::size_t n = world.size();
    report["input_points"] = n;
    const DensityReference reference = choose_reference(views, options.reference, all.have_cameras);
    const bool sensors = reference == DensityReference::kSensors;
    report["reference"] = sensors ? "sensors" : "local";
    const std::size_t k = std::min<std::size_t>(std::size_t(options.k), n > 0 ? n - 1 : 0);
    if (n < 3 || k < 2) return detail::nothing_removed(std::move(report), watch);
    Report stages;
    double lap = 0.0;
    const auto stage = [&](const char* name) {
        const double now = watch.seconds();
        stages[name] = now - lap;
        lap = now;
    };
    stage("gather");
    if (!report_progress(progress, 0.0)) return detail::cancelled(report, watch);
    const double theta_max = options.theta_max_deg * std::numbers::pi / 180.0;

    // With the sensors reference, super-resolved points take their measured parents' expected
    // density and cluster verdict (DensityOptions::judge_synthetic).
    if (sensors && !options.judge_synthetic)
        report["synthetic_followers"] = find_parents(views, all);
    std::vector<Camera> cameras;
    if (sensors) cameras = view_cameras(views, all);
    stage("depth_maps");
    const double spacing = one_view_spacing(all, options.seed);
    report["spacing_m"] = spacing;
    stage("spacing");

    // Measured and expected density of every point.
    std::vector<double> measured(n), expected(n, 0.0);
    Neighbourhoods hood;
    if (sensors) {
        measure_sensor_density(views, all, options.k, spacing, measured, hood);
        report["radius_m"] = hood.radius;
        stage("measured");
        if (!report_progress(progress, 0.3)) return detail::cancelled(report, watch);
        expect_sensor_density(cameras, all, hood, options.noise_model, std::tan(theta_max),
                              expected);
        if (!all.parent.empty())
            tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
                if (!all.own_parent(i)) expected[i] = expected[all.parent[i]];
            });
    } else {
        const internal::KdTree tree(world);
        measure_local_density(tree, world, k, measured);
        if (!report_progress(progress, 0.3)) return detail::cancelled(report, watch);
        const std::size_t k_ref = std::min<std::size_t>(std::size_t(options.k_ref), n - 1);
        expect_local_density(tree, world, measured, k_ref, expected);
    }
    stage("expected");
    if (!report_progress(progress, 0.5)) return detail::cancelled(report, watch);

    std::vector<std::uint8_t> outlier(n, 0);
    report["density"] =
        flag_sparse(measured, expected, sensors ? options.beta : options.beta_local, outlier);

    // Consensus test (sensors reference): a flying pixel 7-10 mm off the surface still finds
    // part of the surface inside its counting sphere (ratio ~ 1 - (d / r)^2 for a plane), so
    // the density test alone misses it. Flag a point that (a) has less than consensus_ratio of
    // its expected density, (b) is seen by its own view at an incidence steeper than theta_max
    // (it sits on a depth discontinuity of that view: a real surface that steep is not
    // measured) and (c) lies more than consensus_sigmas sigma_z (its own view's noise at its
    // depth) off the plane of the OTHER views' points within consensus_radius r (PCA, trimmed
    // twice to 3 sigma_z). Each cue alone flags hundreds of surface points (silhouettes,
    // creases, misaligned patches); together they veto each other's false positives.
    std::size_t consensus_removed = 0;
    if (sensors && options.consensus_ratio > 0.0) {
        const std::vector<std::uint32_t> candidates =
            consensus_candidates(all, cameras, hood.normal, measured, expected, outlier,
                                 options.consensus_ratio, theta_max);
        const std::vector<std::uint8_t> off =
            off_other_views(all, cameras, hood, candidates, options);
        for (std::size_t a = 0; a < candidates.size(); ++a)
            if (off[a]) {
                outlier[candidates[a]] = 1;
                ++consensus_removed;
            }
        report["consensus_candidates"] = candidates.size();
    }
    report["consensus"] = consensus_removed;
    stage("consensus");

    // The cluster pass; with parents, over the measured survivors at their own spacing, the
    // super-resolved points taking their parents' verdict.
    detail::ClusterCount clusters;
    if (options.cluster_spacing > 0.0) {
        if (all.parent.empty()) {
            clusters = detail::flag_small_clusters(world, options.cluster_spacing * spacing,
                                                   options.min_cluster_fraction, outlier, report);
        } else {
            std::vector<std::uint8_t> own(n), before = outlier;
            for (std::size_t i = 0; i < n; ++i) own[i] = all.own_parent(i);
            clusters = detail::flag_small_clusters(
                world, options.cluster_spacing * one_view_spacing(all, options.seed, true),
                options.min_cluster_fraction, outlier, report, &own);
            for (std::size_t i = 0; i < n; ++i)
                if (!own[i] && !outlier[i] && outlier[all.parent[i]] && !before[all.parent[i]]) {
                    outlier[i] = 1;
                    ++clusters.removed;
                }
        }
    }
    report["cluster"] = clusters.removed;
    report["clusters"] = clusters.clusters;
    stage("cluster");

    apply_to_views(views, all, outlier, options.mark, report);
    stage("apply");
    report["stages_s"] = stages;
    return detail::finished(std::move(report), watch, progress);
}

}  // namespace rgbd::denoise
