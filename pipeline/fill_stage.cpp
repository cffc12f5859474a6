#include "pipeline/fill_stage.hpp"

#include <algorithm>
#include <limits>

#include "toolkit/synthetic_view.hpp"

namespace rgbd::pipeline {

Rgb mechanism_color(holes::FillMechanism mechanism) {
    switch (mechanism) {
        case holes::FillMechanism::kLargeHole:
            return {220, 40, 220};
        case holes::FillMechanism::kHeadTop:
            return {40, 210, 230};
        case holes::FillMechanism::kOnePoint:
            return {230, 40, 40};
        case holes::FillMechanism::kFourPoints:
            return {40, 200, 40};
        case holes::FillMechanism::kThreePoints:
            return {40, 80, 230};
        default:
            return {240, 210, 20};
    }
}

std::optional<PointCloud> fill_stage(const std::vector<PointCloud*>& views,
                                     const FillStageOptions& options, Report& report,
                                     const Progress& progress) {
    const auto step = [&](double from, double width) {
        return [&, from, width](double f) { return report_progress(progress, from + width * f); };
    };
    int max_id = -1;
    for (const PointCloud* view : views) max_id = std::max(max_id, view->view.id);
    std::vector<holes::SensorView> sensors;
    // Holes are where no sensor measured: super-resolved points (synthetic) take no part, and
    // the detection works at the sensors' own spacing (about 1/3 of it after upsampling).
    holes::SurfacePoints points =
        holes::gather_views({views.begin(), views.end()}, &sensors, /*measured_only=*/true);
    // Many overlapping frames (a 50-frame sequence) give points far denser than any hole the
    // mesh can show: detect and inpaint on a thinned set (the added points join the full one).
    report["points_measured"] = points.size();
    if (!options.mark && options.max_points > 0 && points.size() > options.max_points) {
        double voxel_m = 0.0;
        points = holes::thin_points(points, options.max_points, &voxel_m);
        report["thinned_to"] = points.size();
        report["thinning_voxel_m"] = voxel_m;
    }
    // The vertical axis comes from the poses even when the visibility test ignores them.
    const std::vector<holes::SensorView> ring = sensors;
    if (options.ignore_poses) sensors.clear();
    report["views"] = views.size();
    report["sensors"] = sensors.size();
    report["points_added_total"] = 0;
    if (points.size() < 4) {
        report["note"] =
            "the stream has " + std::to_string(points.size()) + " points; nothing to fill";
        return std::nullopt;
    }
    const holes::BoundaryResult detection =
        holes::detect_boundaries(points, sensors, options.detect, &report, step(0.0, 0.4));
    Report loops = Report::array();
    for (const auto& loop : detection.loops)
        loops.push_back({{"points", loop.points.size()},
                         {"diameter_m", loop.diameter_m},
                         {"small", loop.small},
                         {"kind", holes::to_string(loop.kind)},
                         {"seen_by", loop.seen_by}});
    report["loop_list"] = loops;
    if (options.mark) {
        std::size_t offset = 0;
        for (PointCloud* view : views) {
            if (view->empty()) continue;
            PointCloud& cloud = *view;
            const auto synthetic = cloud.flag(prop::kSynthetic);
            auto flag = cloud.add_flag(prop::kBoundary);
            auto probability = cloud.add_float(prop::kBoundaryProbability);
            for (auto idx : cloud.points) {
                if (synthetic && (*synthetic)[idx]) {
                    flag[idx] = 0;
                    probability[idx] = 0.0f;
                    continue;
                }
                flag[idx] = detection.boundary[offset];
                probability[idx] = detection.probability[offset++];
            }
        }
    }
    if (options.detect_only) return std::nullopt;
    holes::FillResult added =
        holes::fill_small_holes(points, detection, options.fill, &report, step(0.4, 0.2));
    if (options.head_top || options.large) {
        // Inpainting works on the measured points plus the small-hole fill.
        holes::SurfacePoints all = points;
        std::vector<Eigen::Vector3d> normals = detection.gradient.normal;
        const auto append = [&](const holes::FillResult& more) {
            for (std::size_t i = 0; i < more.position.size(); ++i) {
                all.position.push_back(more.position[i]);
                normals.push_back(more.normal[i]);
                if (!all.color.empty()) all.color.push_back(more.color[i]);
                added.position.push_back(more.position[i]);
                added.normal.push_back(more.normal[i]);
                added.color.push_back(more.color[i]);
                added.mechanism.push_back(more.mechanism[i]);
                added.loop.push_back(more.loop[i]);
            }
        };
        all.normal.clear();
        all.view.clear();
        for (std::size_t i = 0; i < added.position.size(); ++i) {
            all.position.push_back(added.position[i]);
            normals.push_back(added.normal[i]);
            if (!all.color.empty()) all.color.push_back(added.color[i]);
        }
        const holes::BodyAxis axis = holes::estimate_body_axis(points, ring);
        report["axis"] = {{"up", {axis.up.x(), axis.up.y(), axis.up.z()}},
                          {"from_sensors", axis.from_sensors}};
        double top_limit = std::numeric_limits<double>::infinity();
        if (options.head_top) {
            top_limit = holes::head_top_start(all, axis, options.inpaint);
            append(holes::fill_head_top(all, normals, axis, detection.spacing_m, sensors,
                                        options.inpaint, &report, step(0.6, 0.2)));
        }
        if (options.large)
            append(holes::fill_large_holes(all, normals, axis, detection.spacing_m, sensors,
                                           options.inpaint, top_limit, &report, step(0.8, 0.2)));
    }
    report["points_added_total"] = added.position.size();
    if (added.position.empty()) return std::nullopt;
    PointCloud cloud = synthetic_world_view(max_id + 1, "rgbd-fill");
    const auto colors = cloud.colors();
    const auto synthetic = *cloud.flag(prop::kSynthetic);
    const auto mechanism = cloud.add_flag(prop::kFillMechanism);
    for (std::size_t i = 0; i < added.position.size(); ++i) {
        const auto idx = *cloud.points.insert(to_point(added.position[i]));
        cloud.points.normal(idx) =
            Vector_3(added.normal[i].x(), added.normal[i].y(), added.normal[i].z());
        colors.set(idx,
                   options.debug_colors ? mechanism_color(added.mechanism[i]) : added.color[i]);
        synthetic[idx] = 1;
        mechanism[idx] = static_cast<std::uint8_t>(added.mechanism[i]);
    }
    report_progress(progress, 1.0);
    return cloud;
}

}  // namespace rgbd::pipeline
