// Internal helpers of the denoise filters: gathering the live points of a view (finite
// coordinates checked, error naming the view), applying a per-point outlier decision by
// marking (`noise` flag) or deleting with all properties kept aligned, the report of a
// cancelled run, and the disjoint sets of the component passes. Not a public header.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "algorithms/internal/kd_tree.hpp"
#include "toolkit/error.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::denoise::detail {

inline std::string view_name(const PointCloud& cloud) {
    std::string name = "view " + std::to_string(cloud.view.id);
    if (!cloud.view.sensor.empty()) name += " (sensor " + cloud.view.sensor + ")";
    return name;
}

/// The `pixel` map of an organised view (`name`: the view in messages). InputError
/// "<name>: <no_grid>" when the view has no pixel grid, "<name>: <no_pixel>" when it has no
/// `pixel` property.
inline PointCloud::Uint32Map organised_pixels(const PointCloud& cloud, const std::string& name,
                                              const char* no_grid, const char* no_pixel) {
    RGBD_CHECK(cloud.view.has_grid(), name + ": " + no_grid);
    const auto pixel = cloud.pixel_map();
    RGBD_CHECK(pixel.has_value(), name + ": " + no_pixel);
    return *pixel;
}

/// The sensor_from_world pose of a world-frame view; InputError naming the view and the filter
/// (`option`, e.g. "--smooth") when the view has no world_from_sensor pose.
inline Pose sensor_from_world(const PointCloud& cloud, const std::string& name,
                              const char* option) {
    RGBD_CHECK(cloud.view.world_from_sensor.has_value(),
               name + ": a world-frame view needs its world_from_sensor pose for " + option);
    return cloud.view.world_from_sensor->inverse();
}

/// Live points of the cloud in iteration order.
struct Gathered {
    std::vector<Eigen::Vector3d> xyz;
    std::vector<PointSet::Index> ids;
};

/// Throws InputError naming the view for a non-finite coordinate.
inline Gathered gather(const PointCloud& cloud) {
    Gathered g;
    g.xyz.reserve(cloud.size());
    g.ids.reserve(cloud.size());
    std::size_t i = 0;
    for (PointSet::Index idx : cloud.points) {
        const Eigen::Vector3d p = to_eigen(cloud.points.point(idx));
        RGBD_CHECK(p.allFinite(), view_name(cloud) + ": point " + std::to_string(i) +
                                      " has a non-finite coordinate");
        g.xyz.push_back(p);
        g.ids.push_back(idx);
        ++i;
    }
    return g;
}

/// What a filter over one view does first: checks `options` (InputError), opens `report` with
/// the filter's `method` name (and "mark" when the options have a `mark` setting,
/// "noise_model" when they have a `noise_model`), gathers the live points of `cloud` (gather())
/// and records their number as "input_points".
template <class Options>
Gathered open_run(const PointCloud& cloud, const Options& options, const char* method,
                  Report& report) {
    options.check();
    report["method"] = method;
    if constexpr (requires { options.mark; }) report["mark"] = options.mark;
    if constexpr (requires { options.noise_model; })
        report["noise_model"] = to_string(options.noise_model);
    Gathered g = gather(cloud);
    report["input_points"] = g.xyz.size();
    return g;
}

/// Calls visit(i, ids, sq, found) for every point i of `points`, in parallel over chunks of
/// `grain` points: ids[0, found) and sq[0, found) are the indices in `tree` of the (up to) `k`
/// nearest points to points[i] and their squared distances, ascending (a point that is in the
/// tree comes first, at distance 0). The buffers are allocated once per chunk.
template <class Visit>
void for_each_knn(const internal::KdTree& tree, const std::vector<Eigen::Vector3d>& points,
                  std::size_t k, std::size_t grain, const Visit& visit) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), grain),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::vector<std::uint32_t> ids(k);
                          std::vector<double> sq(k);
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const std::size_t found =
                                  tree.knn(points[i], k, ids.data(), sq.data());
                              visit(i, ids.data(), sq.data(), found);
                          }
                      });
}

/// The mean of sqrt(sq[j]) over j in [skip, found): the mean distance to the neighbours of a
/// for_each_knn() visit after the first `skip` (1 skips the point itself); 0 when none is left.
inline double mean_distance(const double* sq, std::size_t found, std::size_t skip) {
    double sum = 0.0;
    for (std::size_t j = skip; j < found; ++j) sum += std::sqrt(sq[j]);
    const std::size_t used = found - std::min(found, skip);
    return used > 0 ? sum / double(used) : 0.0;
}

/// Marks or deletes the points with outlier[i] != 0 (i = position in `g`); returns the count.
inline std::size_t apply(PointCloud& cloud, const Gathered& g,
                         const std::vector<std::uint8_t>& outlier, bool mark) {
    const std::size_t count = static_cast<std::size_t>(
        std::count_if(outlier.begin(), outlier.end(), [](std::uint8_t o) { return o != 0; }));
    if (mark) {
        auto noise = cloud.add_flag(prop::kNoise);
        for (std::size_t i = 0; i < g.ids.size(); ++i)
            if (outlier[i]) noise[g.ids[i]] = 1;
        return count;
    }
    if (count == 0) return 0;
    // Copy the survivors, in order, with all their properties into a fresh point set: O(n)
    // per property, where Point_set_3's remove + collect_garbage sorts every property array.
    PointSet kept;
    kept.copy_properties(cloud.points);
    kept.reserve(g.ids.size() - count);
    for (std::size_t i = 0; i < g.ids.size(); ++i)
        if (!outlier[i]) kept.insert(cloud.points, g.ids[i]);
    cloud.points = std::move(kept);
    return count;
}

/// The report of a run that removes nothing (no points to judge) and ends here.
inline Report nothing_removed(Report report, const Stopwatch& watch) {
    report["removed"] = 0;
    report["time_s"] = watch.seconds();
    return report;
}

/// The report of a run cancelled through its progress callback: nothing removed.
inline Report cancelled(Report report, const Stopwatch& watch) {
    report["cancelled"] = true;
    return nothing_removed(std::move(report), watch);
}

/// Records how many points a filter flagged: "marked" (and "removed" 0) when it only marks
/// them, else "removed".
inline void record_removed(Report& report, std::size_t count, bool mark) {
    report[mark ? "marked" : "removed"] = count;
    if (mark) report["removed"] = 0;
}

/// The report of a finished run: progress 1, total time.
inline Report finished(Report report, const Stopwatch& watch, const Progress& progress) {
    report_progress(progress, 1.0);
    report["time_s"] = watch.seconds();
    return report;
}

/// Union-find over point positions with path halving; the smaller index becomes the root.
class DisjointSets {
public:
    explicit DisjointSets(std::size_t n) : parent_(n) {
        for (std::size_t i = 0; i < n; ++i) parent_[i] = static_cast<std::uint32_t>(i);
    }
    std::uint32_t find(std::uint32_t a) {
        while (parent_[a] != a) {
            parent_[a] = parent_[parent_[a]];
            a = parent_[a];
        }
        return a;
    }
    void unite(std::uint32_t a, std::uint32_t b) {
        a = find(a);
        b = find(b);
        if (a != b) parent_[std::max(a, b)] = std::min(a, b);
    }

private:
    std::vector<std::uint32_t> parent_;
};

}  // namespace rgbd::denoise::detail
