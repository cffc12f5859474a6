#include "algorithms/denoise/statistical_outliers.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "algorithms/denoise/outlier_common.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "algorithms/sampling/robust_spacing.hpp"
#include "toolkit/error.hpp"

namespace rgbd::denoise {

void StatisticalOptions::check() const {
    check_range("statistical outliers: k", k, Range::closed(1, 10000));
    RGBD_CHECK(std::isfinite(std_ratio) && std_ratio >= 0.0 && std_ratio <= 1e6,
               "statistical outliers: std_ratio must be finite and >= 0");
}

void RadiusOptions::check() const {
    check_range("radius outliers: min_points", min_points, Range::closed(0, 100000));
    RGBD_CHECK(std::isfinite(radius_m) && radius_m >= 0.0,
               "radius outliers: radius_m must be finite and >= 0 (0 = from spacing)");
    check_range("radius outliers: radius_spacing_factor", radius_spacing_factor,
                Range::open_closed(0.0, 1e4));
}

namespace {

const char* convention_name(OutlierConvention c) {
    return c == OutlierConvention::kOpen3d ? "open3d" : "pcl";
}

using detail::apply;
using detail::cancelled;
using detail::finished;
using detail::for_each_knn;
using detail::Gathered;
using detail::nothing_removed;
using detail::open_run;
using detail::record_removed;
using detail::view_name;

}  // namespace

Report remove_statistical_outliers(PointCloud& cloud, const StatisticalOptions& options,
                                   const Progress& progress) {
    Stopwatch watch;
    Report report;
    const Gathered g = open_run(cloud, options, "statistical", report);
    const std::size_t n = g.xyz.size();
    report["convention"] = convention_name(options.convention);
    report["k_requested"] = options.k;
    report["std_ratio"] = options.std_ratio;
    if (!report_progress(progress, 0.0)) return cancelled(report, watch);

    const bool open3d = options.convention == OutlierConvention::kOpen3d;
    // Open3D counts the point itself among its k; PCL searches k + 1 and drops the first.
    const std::size_t k_max = open3d ? n : (n > 0 ? n - 1 : 0);
    const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(options.k), k_max);
    report["k"] = k;
    report["k_clamped"] = k < static_cast<std::size_t>(options.k);
    if (n == 0 || k == 0) return nothing_removed(std::move(report), watch);

    const internal::KdTree tree(g.xyz);
    std::vector<double> mean_distance(n);
    const std::size_t search = open3d ? k : k + 1;
    const std::size_t skip = open3d ? 0 : 1;
    for_each_knn(tree, g.xyz, search, 512,
                 [&](std::size_t i, const std::uint32_t*, const double* sq, std::size_t found) {
                     const double mean = detail::mean_distance(sq, found, skip);
                     // PCL stores the per-point mean as float.
                     mean_distance[i] = open3d ? mean : double(float(mean));
                 });
    if (!report_progress(progress, 0.8)) return cancelled(report, watch);

    // Sequential reductions in index order: the result is independent of the thread count.
    std::vector<std::uint8_t> outlier(n, 0);
    double mean = 0.0, stddev = 0.0, threshold = 0.0;
    if (open3d) {
        double sum = 0.0;
        for (double d : mean_distance)
            if (d > 0.0) sum += d;
        mean = sum / double(n);
        double sq_sum = 0.0;
        for (double d : mean_distance)
            if (d > 0.0) sq_sum += (d - mean) * (d - mean);
        stddev = n > 1 ? std::sqrt(sq_sum / double(n - 1)) : 0.0;
        threshold = mean + options.std_ratio * stddev;
        for (std::size_t i = 0; i < n; ++i)
            outlier[i] = !(mean_distance[i] > 0.0 && mean_distance[i] < threshold);
    } else {
        double sum = 0.0, sq_sum = 0.0;
        for (double d : mean_distance) {
            const float f = static_cast<float>(d);
            sum += f;
            sq_sum += static_cast<double>(f * f);
        }
        mean = sum / double(n);
        const double variance =
            n > 1 ? std::max(0.0, (sq_sum - sum * sum / double(n)) / double(n - 1)) : 0.0;
        stddev = std::sqrt(variance);
        threshold = mean + options.std_ratio * stddev;
        for (std::size_t i = 0; i < n; ++i) outlier[i] = mean_distance[i] > threshold;
    }
    report["mean_distance_m"] = mean;
    report["std_distance_m"] = stddev;
    report["threshold_m"] = threshold;
    record_removed(report, apply(cloud, g, outlier, options.mark), options.mark);
    return finished(std::move(report), watch, progress);
}

Report remove_radius_outliers(PointCloud& cloud, const RadiusOptions& options,
                              const Progress& progress) {
    Stopwatch watch;
    Report report;
    const Gathered g = open_run(cloud, options, "radius", report);
    const std::size_t n = g.xyz.size();
    report["convention"] = convention_name(options.convention);
    report["min_points"] = options.min_points;
    if (!report_progress(progress, 0.0)) return cancelled(report, watch);
    if (n == 0) {
        report["radius_m"] = options.radius_m;
        return nothing_removed(std::move(report), watch);
    }

    double radius = options.radius_m;
    if (radius <= 0.0) {
        // Fewer than two points have no spacing (0): the check below names the view.
        const double spacing =
            n >= 2 ? sampling::robust_spacing(cloud.points, 10000, options.seed) : 0.0;
        report["spacing_m"] = spacing;
        report["radius_spacing_factor"] = options.radius_spacing_factor;
        radius = options.radius_spacing_factor * spacing;
        RGBD_CHECK(radius > 0.0, view_name(cloud) +
                                     ": cannot derive a radius, the robust point spacing is 0 "
                                     "(give radius_m)");
    }
    report["radius_m"] = radius;

    // count(incl. self) > min_points  <=>  the (min_points + 1)-th nearest neighbour (self
    // first) lies within the radius: strictly (Open3D, nanoflann radius search) or not (PCL).
    const std::size_t need = static_cast<std::size_t>(options.min_points) + 1;
    const double r2 = radius * radius;
    const bool open3d = options.convention == OutlierConvention::kOpen3d;
    const internal::KdTree tree(g.xyz);
    std::vector<std::uint8_t> outlier(n, 0);
    for_each_knn(tree, g.xyz, need, 512,
                 [&](std::size_t i, const std::uint32_t*, const double* sq, std::size_t found) {
                     bool keep = found == need;
                     if (keep) keep = open3d ? sq[need - 1] < r2 : sq[need - 1] <= r2;
                     outlier[i] = !keep;
                 });
    if (!report_progress(progress, 0.8)) return cancelled(report, watch);
    record_removed(report, apply(cloud, g, outlier, options.mark), options.mark);
    return finished(std::move(report), watch, progress);
}

}  // namespace rgbd::denoise
