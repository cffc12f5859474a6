#include "algorithms/normals/estimate_normals.hpp"

#include <CGAL/mst_orient_normals.h>
#include <CGAL/property_map.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define RGBD_NORMALS_AVX2 1
#endif

#include "algorithms/internal/cell_grid.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"

namespace rgbd::normals {

namespace {
constexpr EnumName<NormalOrientation> kOrientationNames[] = {
    {NormalOrientation::kAuto, "auto"},
    {NormalOrientation::kSensor, "sensor"},
    {NormalOrientation::kMst, "mst"},
    {NormalOrientation::kOutward, "outward"},
    {NormalOrientation::kNone, "none"}};
}  // namespace

const char* to_string(NormalOrientation orientation) {
    return name_of(kOrientationNames, orientation);
}

void NormalOptions::check() const {
    RGBD_CHECK(k >= 3 && k <= 1024, "normals: k must be in [3, 1024], got " + std::to_string(k));
    RGBD_CHECK(mst_k >= 2 && mst_k <= 1024,
               "normals: mst_k must be in [2, 1024], got " + std::to_string(mst_k));
    for (const auto& [id, centre] : sensor_centres)
        RGBD_CHECK(centre.allFinite(),
                   "normals: sensor centre of view " + std::to_string(id) + " is not finite");
}

namespace {

constexpr std::size_t kChunk = 1024;

std::string view_name(const PointCloud& cloud) { return "view " + std::to_string(cloud.view.id); }

/// Sensor centre of a single-sensor view in the cloud's own frame, if known.
std::optional<Eigen::Vector3d> view_sensor_centre(const PointCloud& cloud) {
    if (cloud.view.frame == ViewFrame::kSensor) return Eigen::Vector3d::Zero();
    if (cloud.view.world_from_sensor) return cloud.view.world_from_sensor->translation();
    return std::nullopt;
}

/// Normal of the points `nn[0, found)` (nearest first): the eigenvector of the smallest
/// eigenvalue of their covariance, with the deterministic sign (largest component positive).
/// Sets `degenerate` for collinear or coincident neighbours.
Eigen::Vector3d pca_normal(const std::vector<Eigen::Vector3d>& xyz, const std::uint32_t* nn,
                           std::size_t found, char& degenerate) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t j = 0; j < found; ++j) mean += xyz[nn[j]];
    mean /= static_cast<double>(found);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (std::size_t j = 0; j < found; ++j) {
        const Eigen::Vector3d d = xyz[nn[j]] - mean;
        cov.noalias() += d * d.transpose();
    }
    // The closed-form 3 x 3 solver (as the density filter, hole detection and point smoothing
    // use): a person view's normals take ~17% less CPU than with the iterative one, the same
    // normal within 1e-12 on the tests' surface patches.
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(cov);
    Eigen::Vector3d normal = eig.eigenvectors().col(0);
    const Eigen::Vector3d ev = eig.eigenvalues();
    if (found < 3 || !normal.allFinite() || ev(1) <= 1e-14 * std::max(ev(2), 1e-300)) {
        degenerate = 1;  // collinear or coincident neighbours
        if (!normal.allFinite()) normal = Eigen::Vector3d::UnitZ();
    }
    Eigen::Index arg;
    normal.cwiseAbs().maxCoeff(&arg);
    if (normal(arg) < 0) normal = -normal;
    return normal.normalized();
}

/// kNN neighbourhoods through a kd-tree (any cloud): one PCA per point, fixed chunks; each
/// point's result depends only on its neighbourhood.
Report knn_normals(const std::vector<Eigen::Vector3d>& xyz, const NormalOptions& options,
                   const Progress& progress, std::vector<Eigen::Vector3d>& normals,
                   std::vector<char>& degenerate, std::atomic<bool>& cancelled,
                   std::vector<std::uint32_t>* neighbours) {
    const std::size_t n = xyz.size();
    const internal::KdTree tree(xyz);
    const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(options.k), n);
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    if (neighbours) neighbours->assign(n * k, 0);
    std::atomic<std::size_t> done{0};
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
        if (cancelled.load(std::memory_order_relaxed)) return;
        std::vector<std::uint32_t> nn(k);
        std::vector<double> sq(k);
        const std::size_t begin = c * kChunk, end = std::min(n, begin + kChunk);
        for (std::size_t i = begin; i < end; ++i) {
            const std::size_t found = tree.knn(xyz[i], k, nn.data(), sq.data());
            normals[i] = pca_normal(xyz, nn.data(), found, degenerate[i]);
            if (neighbours) std::copy(nn.begin(), nn.begin() + found, neighbours->begin() + i * k);
        }
        const std::size_t so_far = done.fetch_add(end - begin) + (end - begin);
        if (progress && c % 16 == 0 && !report_progress(progress, 0.9 * so_far / n))
            cancelled = true;
    });
    return {{"method", "knn"}};
}

/// An organised view's points bucketed by depth pixel: pixel p's points are
/// point[start[p], start[p + 1]) (by point order), and the window half-width that gives about
/// 1.5 k candidates at the view's mean number of points per occupied pixel.
struct PixelBuckets {
    int width = 0, height = 0;
    std::vector<std::uint32_t> start, point;
    std::vector<std::uint32_t> occupied;  ///< pixels holding at least one point, ascending
    int half_window = 1;
};

/// The buckets of a sensor-frame view with a pixel grid and a pixel per point, when
/// options.pixel_grid allows; nullopt otherwise (the kd-tree path).
std::optional<PixelBuckets> organised_grid(const PointCloud& cloud,
                                           const std::vector<PointSet::Index>& index,
                                           const NormalOptions& options) {
    if (!options.pixel_grid || !cloud.view.has_grid() || cloud.view.frame != ViewFrame::kSensor)
        return std::nullopt;
    const auto pixel = cloud.pixel_map();
    if (!pixel) return std::nullopt;
    PixelBuckets b;
    b.width = cloud.view.grid_width;
    b.height = cloud.view.grid_height;
    const std::size_t pixels = static_cast<std::size_t>(b.width) * b.height;
    b.start.assign(pixels + 1, 0);
    for (const auto idx : index) {
        const std::uint32_t p = (*pixel)[idx];
        if (p >= pixels) return std::nullopt;  // a pixel outside the grid: not organised
        ++b.start[p + 1];
    }
    for (std::size_t p = 0; p < pixels; ++p) {
        if (b.start[p + 1] > 0) b.occupied.push_back(static_cast<std::uint32_t>(p));
        b.start[p + 1] += b.start[p];
    }
    b.point.resize(index.size());
    std::vector<std::uint32_t> fill(b.start.begin(), b.start.end() - 1);
    for (std::size_t i = 0; i < index.size(); ++i)
        b.point[fill[(*pixel)[index[i]]]++] = static_cast<std::uint32_t>(i);
    // A window of about 1.5 k points at the view's mean number of points per occupied pixel.
    const double per_pixel = static_cast<double>(index.size()) / b.occupied.size();
    const double side = std::sqrt(1.5 * options.k / per_pixel);
    b.half_window = std::clamp(static_cast<int>(std::ceil((side - 1.0) / 2.0)), 1, 4);
    return b;
}

#if defined(RGBD_NORMALS_AVX2)
/// Windows of up to this many points are selected by rank (rank_select_avx2) where AVX2 runs.
constexpr std::size_t kRankSelectMax = 64;

/// Places each of the m <= 64 window points at its rank among the (squared distance, index)
/// pairs (d[j], w[j]), both padded to a multiple of 4 (d with +inf): nn[r] = w[i] for the rank
/// r = #{j : d[j] < d[i] or (d[j] == d[i] and w[j] < w[i])} when r < found. The ranks are
/// counted four pairs at a time without branches (m^2 / 4 steps, where nth_element's
/// data-dependent branches mispredict about every other comparison). Equal distances are common
/// (a depth pixel's left and right neighbours at the same quantised depth).
__attribute__((target("avx2"))) void rank_select_avx2(const double* d, const std::int64_t* w,
                                                      std::size_t m, std::size_t found,
                                                      std::uint32_t* nn) {
    for (std::size_t i = 0; i < m; ++i) {
        const __m256d di = _mm256_set1_pd(d[i]);
        const __m256i wi = _mm256_set1_epi64x(w[i]);
        __m256i lanes = _mm256_setzero_si256();  // minus the count in each lane
        for (std::size_t j = 0; j < m; j += 4) {
            const __m256d dj = _mm256_loadu_pd(d + j);
            const __m256i wj = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(w + j));
            const __m256i before = _mm256_or_si256(
                _mm256_castpd_si256(_mm256_cmp_pd(dj, di, _CMP_LT_OQ)),
                _mm256_and_si256(_mm256_castpd_si256(_mm256_cmp_pd(dj, di, _CMP_EQ_OQ)),
                                 _mm256_cmpgt_epi64(wi, wj)));
            lanes = _mm256_add_epi64(lanes, before);
        }
        alignas(32) std::int64_t sums[4];
        _mm256_store_si256(reinterpret_cast<__m256i*>(sums), lanes);
        const std::uint64_t rank = std::uint64_t(-(sums[0] + sums[1] + sums[2] + sums[3]));
        if (rank < found) nn[rank] = static_cast<std::uint32_t>(w[i]);
    }
}

/// How many of d[0, m) (padded to a multiple of 4 with +inf) are <= t.
__attribute__((target("avx2,popcnt"))) std::size_t count_at_most_avx2(const double* d,
                                                                      std::size_t m, double t) {
    const __m256d tt = _mm256_set1_pd(t);
    std::size_t count = 0;
    for (std::size_t j = 0; j < m; j += 4)
        count += std::size_t(__builtin_popcount(
            _mm256_movemask_pd(_mm256_cmp_pd(_mm256_loadu_pd(d + j), tt, _CMP_LE_OQ))));
    return count;
}

/// Keeps in place, in order, the pairs (d[j], w[j]) of j < m that can be among the `found`
/// smallest: those with d[j] <= t for a bound t that at least `found` of them meet (the
/// found-th smallest distance is then <= t, so every pair beyond t ranks after the found
/// smallest, and ranks among the kept pairs equal the ranks among all). t by a few bisection
/// steps between the smallest and the largest distance, each a vector count; the exact ranks
/// then cost (kept / m)^2 of ranking the whole window. Returns the count kept, padded with +inf
/// to a multiple of 4.
std::size_t keep_candidates_avx2(double* d, std::int64_t* w, std::size_t m, std::size_t found) {
    double lo = d[0], hi = d[0];
    for (std::size_t j = 1; j < m; ++j) {
        lo = std::min(lo, d[j]);
        hi = std::max(hi, d[j]);
    }
    // Stop once the bound keeps at most an eighth more than needed.
    const std::size_t enough = found + found / 8 + 1;
    for (int step = 0; step < 6; ++step) {
        const double mid = lo + 0.5 * (hi - lo);
        const std::size_t count = count_at_most_avx2(d, m, mid);
        if (count >= found) {
            hi = mid;
            if (count <= enough) break;
        } else {
            lo = mid;
        }
    }
    std::size_t kept = 0;
    for (std::size_t j = 0; j < m; ++j)
        if (d[j] <= hi) {
            d[kept] = d[j];
            w[kept] = w[j];
            ++kept;
        }
    const std::size_t padded = (kept + 3) / 4 * 4;
    for (std::size_t j = kept; j < padded; ++j) d[j] = std::numeric_limits<double>::infinity();
    return kept;
}
#endif

/// The min(k, window.size()) points of `window` nearest to q, nearest first, ties by index:
/// the smallest (squared distance, index) pairs, written to nn; returns the count. Windows of
/// up to 64 points on a CPU with AVX2 (the usual 7 x 7 pixels of a point per pixel) by rank
/// (rank_select_avx2, x86-64 builds); otherwise the smallest pairs selected in one pass
/// (nth_element) and only those sorted. Both give the same order. `dist`, `index` and `candidates`
/// are reused buffers.
std::size_t nearest_in_window(const std::vector<Eigen::Vector3d>& xyz,
                              const std::vector<std::uint32_t>& window, const Eigen::Vector3d& q,
                              std::size_t k, [[maybe_unused]] std::vector<double>& dist,
                              [[maybe_unused]] std::vector<std::int64_t>& index,
                              std::vector<std::pair<double, std::uint32_t>>& candidates,
                              std::vector<std::uint32_t>& nn) {
    const std::size_t m = window.size(), found = std::min(k, m);
    nn.resize(found);
    if (found == 0) return 0;
#if defined(RGBD_NORMALS_AVX2)
    static const bool avx2 = __builtin_cpu_supports("avx2");
    if (avx2 && m <= kRankSelectMax) {
        const std::size_t padded = (m + 3) / 4 * 4;
        dist.assign(padded, std::numeric_limits<double>::infinity());
        index.assign(padded, 0);
        for (std::size_t j = 0; j < m; ++j) {
            dist[j] = (xyz[window[j]] - q).squaredNorm();
            index[j] = window[j];
        }
        const std::size_t kept =
            found < m ? keep_candidates_avx2(dist.data(), index.data(), m, found) : m;
        rank_select_avx2(dist.data(), index.data(), kept, found, nn.data());
        return found;
    }
#endif
    candidates.resize(m);
    for (std::size_t j = 0; j < m; ++j)
        candidates[j] = {(xyz[window[j]] - q).squaredNorm(), window[j]};
    if (found < m)
        std::nth_element(candidates.begin(), candidates.begin() + (found - 1), candidates.end());
    std::sort(candidates.begin(), candidates.begin() + found);
    for (std::size_t j = 0; j < found; ++j) nn[j] = candidates[j].second;
    return found;
}

/// Organised views: the neighbours of a depth pixel are the k points nearest (in 3D) to its
/// first point among the points of the (2 h + 1)^2 pixels around it (the window sized from the
/// points per pixel, so that the nearest k are inside it as with a kd-tree's kNN on the
/// surface; across a depth edge the nearest are those of the same surface). One PCA per pixel,
/// shared by the pixel's points (super-resolution's points lie within the pixel's footprint).
Report grid_normals(const PixelBuckets& b, const std::vector<Eigen::Vector3d>& xyz,
                    const NormalOptions& options, const Progress& progress,
                    std::vector<Eigen::Vector3d>& normals, std::vector<char>& degenerate,
                    std::atomic<bool>& cancelled) {
    const std::size_t k = static_cast<std::size_t>(options.k);
    const std::size_t count = b.occupied.size();
    const std::size_t chunks = (count + kChunk - 1) / kChunk;
    std::atomic<std::size_t> done{0};
    const int h = b.half_window;
    std::vector<char> sparse(count, 0);
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) {
        if (cancelled.load(std::memory_order_relaxed)) return;
        std::vector<std::pair<double, std::uint32_t>> candidates;
        std::vector<double> dist;
        std::vector<std::int64_t> index;
        std::vector<std::uint32_t> nn, window;
        const std::size_t begin = c * kChunk, end = std::min(count, begin + kChunk);
        for (std::size_t o = begin; o < end; ++o) {
            const std::uint32_t p = b.occupied[o];
            const int row = static_cast<int>(p / b.width), col = static_cast<int>(p % b.width);
            window.clear();
            for (int r = std::max(0, row - h); r <= std::min(b.height - 1, row + h); ++r) {
                const std::size_t first = static_cast<std::size_t>(r) * b.width;
                const std::uint32_t a0 = b.start[first + std::max(0, col - h)];
                const std::uint32_t a1 = b.start[first + std::min(b.width - 1, col + h) + 1];
                window.insert(window.end(), b.point.begin() + a0, b.point.begin() + a1);
            }
            if (2 * window.size() < k) {  // a sparse patch: the kd-tree reaches further
                sparse[o] = 1;
                continue;
            }
            // One PCA per pixel: the k points of the window nearest to the pixel's first
            // (measured) point; the pixel's other points (super-resolution's) share it.
            const Eigen::Vector3d& q = xyz[b.point[b.start[p]]];
            const std::size_t found =
                nearest_in_window(xyz, window, q, k, dist, index, candidates, nn);
            char degenerate_pixel = 0;
            const Eigen::Vector3d normal = pca_normal(xyz, nn.data(), found, degenerate_pixel);
            for (std::uint32_t a = b.start[p]; a < b.start[p + 1]; ++a) {
                normals[b.point[a]] = normal;
                degenerate[b.point[a]] = degenerate_pixel;
            }
        }
        const std::size_t so_far = done.fetch_add(end - begin) + (end - begin);
        if (progress && c % 16 == 0 && !report_progress(progress, 0.9 * so_far / count))
            cancelled = true;
    });
    if (cancelled) return {};
    // Pixels with fewer than k / 2 points in their window: each point's kNN over the view. A
    // few points a view (8 on a Kinect v1 view of a person): on cell grids, whose build is a
    // parallel binning, rather than a kd-tree whose sequential build costs as much as a
    // thousand of these queries. The same neighbours, nearest first.
    std::vector<std::uint32_t> sparse_points;
    for (std::size_t o = 0; o < count; ++o)
        if (sparse[o])
            for (std::uint32_t a = b.start[b.occupied[o]]; a < b.start[b.occupied[o] + 1]; ++a)
                sparse_points.push_back(b.point[a]);
    if (!sparse_points.empty()) {
        const internal::PointSearch search(xyz);
        const std::size_t kk = std::min(k, xyz.size());
        tbb::parallel_for(std::size_t{0}, sparse_points.size(), [&](std::size_t s) {
            std::uint32_t nn[1024];
            double sq[1024];
            const std::uint32_t i = sparse_points[s];
            const std::size_t found = search.knn(xyz[i], kk, nn, sq);
            normals[i] = pca_normal(xyz, nn, found, degenerate[i]);
        });
    }
    return {{"method", "pixel_grid"},
            {"half_window_px", h},
            {"pixels", count},
            {"points_by_knn", sparse_points.size()}};
}

void orient_mst(const std::vector<Eigen::Vector3d>& xyz, std::vector<Eigen::Vector3d>& normals,
                int mst_k, std::size_t& unoriented) {
    std::vector<Point_3> pts(xyz.size());
    std::vector<Vector_3> nrm(xyz.size());
    for (std::size_t i = 0; i < xyz.size(); ++i) {
        pts[i] = to_point(xyz[i]);
        nrm[i] = to_vector(normals[i]);
    }
    std::vector<std::size_t> order(xyz.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    auto first_unoriented =
        CGAL::mst_orient_normals(order, static_cast<unsigned int>(mst_k),
                                 CGAL::parameters::point_map(CGAL::make_property_map(pts))
                                     .normal_map(CGAL::make_property_map(nrm)));
    // Leftovers (other connected components) are oriented away from the centroid.
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (const auto& p : xyz) centroid += p;
    centroid /= static_cast<double>(xyz.size());
    std::vector<char> oriented(xyz.size(), 1);
    for (auto it = first_unoriented; it != order.end(); ++it) oriented[*it] = 0;
    unoriented = static_cast<std::size_t>(order.end() - first_unoriented);
    for (std::size_t i = 0; i < xyz.size(); ++i) {
        Eigen::Vector3d n = to_eigen(nrm[i]);
        if (!oriented[i] && n.dot(xyz[i] - centroid) < 0) n = -n;
        normals[i] = n;
    }
}

}  // namespace

Report estimate_normals(PointCloud& cloud, const NormalOptions& options, const Progress& progress,
                        std::vector<std::uint32_t>* neighbours) {
    if (neighbours) neighbours->clear();
    options.check();
    Stopwatch watch;
    const std::size_t n = cloud.size();
    RGBD_CHECK(n >= 3, "normals: " + view_name(cloud) + ": needs at least 3 points, got " +
                           std::to_string(n));

    std::vector<PointSet::Index> index;
    std::vector<Eigen::Vector3d> xyz;
    index.reserve(n);
    xyz.reserve(n);
    for (auto idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        RGBD_CHECK(p.allFinite(), "normals: " + view_name(cloud) + ": point " +
                                      std::to_string(xyz.size()) + " is not finite");
        index.push_back(idx);
        xyz.push_back(p);
    }

    // Resolve the orientation rule.
    NormalOrientation rule = options.orientation;
    const std::optional<Eigen::Vector3d> centre = view_sensor_centre(cloud);
    const auto view_ids = cloud.view_map();
    const bool per_view = !options.sensor_centres.empty() && view_ids.has_value();
    if (rule == NormalOrientation::kAuto)
        rule = (per_view || centre) ? NormalOrientation::kSensor : NormalOrientation::kMst;
    RGBD_CHECK(rule != NormalOrientation::kSensor || per_view || centre,
               "normals: " + view_name(cloud) +
                   ": orientation 'sensor' needs a sensor-frame view, a world_from_sensor pose "
                   "or sensor_centres with a view property");

    std::vector<Eigen::Vector3d> normals(n);
    std::vector<char> degenerate(n, 0);
    std::atomic<bool> cancelled{false};
    Report method;
    if (const auto grid = organised_grid(cloud, index, options)) {
        method = grid_normals(*grid, xyz, options, progress, normals, degenerate, cancelled);
    } else {
        method = knn_normals(xyz, options, progress, normals, degenerate, cancelled, neighbours);
    }
    if (cancelled) throw AlgorithmError("normals: " + view_name(cloud) + ": cancelled");

    std::size_t flipped = 0, unoriented = 0;
    if (rule == NormalOrientation::kSensor || rule == NormalOrientation::kOutward) {
        Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
        for (const auto& p : xyz) centroid += p;
        centroid /= static_cast<double>(n);
        for (std::size_t i = 0; i < n; ++i) {
            bool flip = false;
            if (rule == NormalOrientation::kOutward) {
                flip = normals[i].dot(xyz[i] - centroid) < 0;
            } else {
                const Eigen::Vector3d* c = centre ? &*centre : nullptr;
                if (per_view) {
                    auto it = options.sensor_centres.find((*view_ids)[index[i]]);
                    if (it != options.sensor_centres.end()) c = &it->second;
                }
                if (c)
                    flip = normals[i].dot(*c - xyz[i]) < 0;
                else
                    ++unoriented;
            }
            if (flip) {
                normals[i] = -normals[i];
                ++flipped;
            }
        }
    } else if (rule == NormalOrientation::kMst) {
        orient_mst(xyz, normals, options.mst_k, unoriented);
    }

    if (!cloud.points.has_normal_map()) cloud.points.add_normal_map();
    for (std::size_t i = 0; i < n; ++i) cloud.points.normal(index[i]) = to_vector(normals[i]);
    report_progress(progress, 1.0);

    std::size_t degenerate_count = 0;
    for (char d : degenerate) degenerate_count += d ? 1 : 0;
    Report report;
    report["k"] = options.k;
    report["neighbours"] = method;
    report["orientation"] = to_string(rule);
    report["points"] = n;
    report["flipped"] = flipped;
    report["unoriented"] = unoriented;
    report["degenerate"] = degenerate_count;
    report["time_s"] = watch.seconds();
    return report;
}

}  // namespace rgbd::normals
