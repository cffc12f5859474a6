// Surface samples for hole detection (docs/algorithms.md §9-§11): the views gathered into one
// world-frame set of measured points, and that set thinned on a voxel grid for merged
// sequences. See also: hole_detection.cpp (the criteria), pipeline/fill_stage.cpp (the stage).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "algorithms/holes/hole_detection.hpp"
#include "algorithms/internal/voxel_grid.hpp"
#include "toolkit/error.hpp"

namespace rgbd::holes {

SurfacePoints gather_views(const std::vector<const PointCloud*>& views,
                           std::vector<SensorView>* sensors, bool measured_only) {
    SurfacePoints out;
    bool normals = true, colors = true;
    std::size_t total = 0, non_empty = 0;
    for (const PointCloud* v : views) {
        if (v->empty()) continue;
        total += v->size();
        ++non_empty;
        normals = normals && v->points.has_normal_map();
        colors = colors && v->has_colors();
    }
    out.position.reserve(total);
    if (normals) out.normal.reserve(total);
    if (colors) out.color.reserve(total);
    out.view.reserve(total);
    for (const PointCloud* v : views) {
        if (v->empty()) continue;
        // A lone sensor-frame view without a pose (a plain point file) is taken as it is.
        Pose world_from_view = Pose::Identity();
        const bool lone = non_empty == 1;
        if (v->view.frame == ViewFrame::kSensor) {
            RGBD_CHECK(
                v->view.world_from_sensor.has_value() || lone,
                "view " + std::to_string(v->view.id) + " is in its sensor frame and has no pose");
            if (v->view.world_from_sensor) world_from_view = *v->view.world_from_sensor;
        }
        int sensor = -1;
        if (sensors && v->view.world_from_sensor) {
            sensor = static_cast<int>(sensors->size());
            sensors->push_back({*v->view.world_from_sensor, v->view.intrinsics});
        }
        const auto color_maps = colors ? std::optional(v->colors()) : std::nullopt;
        const auto synthetic = measured_only ? v->flag(prop::kSynthetic) : std::nullopt;
        for (auto idx : v->points) {
            if (synthetic && (*synthetic)[idx]) continue;
            out.position.push_back(world_from_view * to_eigen(v->points.point(idx)));
            if (normals)
                out.normal.push_back(
                    (world_from_view.linear() * to_eigen(v->points.normal(idx))).normalized());
            if (colors) out.color.push_back(color_maps->get(idx));
            out.view.push_back(sensor);
        }
    }
    return out;
}

SurfacePoints thin_points(const SurfacePoints& points, std::size_t max_points, double* voxel_m) {
    if (voxel_m) *voxel_m = 0.0;
    const std::size_t n = points.size();
    if (max_points == 0 || n <= max_points) return points;
    Eigen::AlignedBox3d box;
    for (std::size_t i = 0; i < n; ++i) {
        RGBD_CHECK(points.position[i].allFinite(),
                   "thin_points: point " + std::to_string(i) + " is not finite");
        box.extend(points.position[i]);
    }
    const double diagonal = std::max(box.diagonal().norm(), 1e-9);
    const double finest = diagonal / static_cast<double>(internal::kVoxelAxisMax);
    internal::VoxelKeyed keyed;
    double keyed_edge = 0.0;  // the edge `keyed` holds
    std::vector<std::size_t> starts;
    const auto occupied = [&](double edge) {
        internal::sort_by_voxel(points.position, box.min(), edge, keyed);
        keyed_edge = edge;
        starts = internal::voxel_starts(keyed);
        return starts.size() - 1;
    };
    // Occupied voxels of a surface fall as about 1/edge^2: start where a flat square of the
    // box's diagonal would fit, correct by the square root of the ratio, and once the budget
    // has been crossed both ways bisect between the finest edge that fits and the coarsest that
    // does not (the count is not smooth in the edge on regular samplings).
    double edge = std::max(diagonal / std::sqrt(static_cast<double>(max_points)), finest);
    double fits = std::numeric_limits<double>::infinity(), too_fine = 0.0;
    for (int pass = 0; pass < 14; ++pass) {
        const std::size_t count = occupied(edge);
        if (count <= max_points) {
            fits = std::min(fits, edge);
            if (count >= max_points * 7 / 10) break;
        } else {
            too_fine = std::max(too_fine, edge);
        }
        const double ratio = static_cast<double>(count) / static_cast<double>(max_points);
        edge = too_fine > 0.0 && std::isfinite(fits) ? 0.5 * (too_fine + fits)
                                                     : edge * std::sqrt(ratio / 0.85);
        if (edge <= finest) break;  // the finest grid fits
    }
    if (!std::isfinite(fits)) {  // never fitted in the passes: grow until it does
        fits = std::max(edge, too_fine);
        while (occupied(fits) > max_points) fits *= 1.1;
    }
    if (keyed_edge != fits) occupied(fits);
    SurfacePoints out;
    const std::size_t voxels = starts.size() - 1;
    out.position.reserve(voxels);
    if (!points.normal.empty()) out.normal.reserve(voxels);
    if (!points.color.empty()) out.color.reserve(voxels);
    if (!points.view.empty()) out.view.reserve(voxels);
    for (std::size_t g = 0; g < voxels; ++g) {
        // The point nearest the voxel's centre (not its points' centroid): kept points then lie
        // about one edge apart everywhere, a regular sampling the detection's spacing describes.
        const Eigen::Vector3d centre =
            internal::voxel_centre(keyed[starts[g]].first, box.min(), fits);
        const std::uint32_t best =
            internal::nearest_in_voxel(keyed, starts[g], starts[g + 1], points.position, centre);
        out.position.push_back(points.position[best]);
        if (!points.normal.empty()) out.normal.push_back(points.normal[best]);
        if (!points.color.empty()) out.color.push_back(points.color[best]);
        if (!points.view.empty()) out.view.push_back(points.view[best]);
    }
    if (voxel_m) *voxel_m = fits;
    return out;
}

}  // namespace rgbd::holes
