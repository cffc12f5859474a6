#include "pipeline/video_fusion.hpp"

#include <algorithm>
#include <cmath>

#include "algorithms/frames/object_extraction.hpp"
#include "algorithms/sampling/merge_views.hpp"
#include "algorithms/sampling/voxel_downsample.hpp"
#include "toolkit/error.hpp"

namespace rgbd::pipeline {

void VideoFusionOptions::check() const {
    cloud.check();
    distance.check();
    RGBD_CHECK(std::isfinite(voxel_m) && voxel_m >= 0 && voxel_m <= 0.5,
               "video fusion: voxel must be in [0, 0.5] m (0 = from the rig)");
    RGBD_CHECK(std::isfinite(duplicate_radius_voxels) && duplicate_radius_voxels >= 0 &&
                   duplicate_radius_voxels <= 10,
               "video fusion: duplicate radius must be in [0, 10] voxels");
    RGBD_CHECK(std::isfinite(max_delta_e) && max_delta_e >= 0,
               "video fusion: max Delta E must be >= 0");
    RGBD_CHECK(std::isfinite(extraction.crop_radius_m) && extraction.crop_radius_m >= 0,
               "video fusion: crop radius must be >= 0");
}

double video_voxel_m(const io::Rig& rig, const std::optional<Eigen::Vector3d>& centre) {
    std::vector<double> footprints;
    for (const io::SensorSpec& s : rig.sensors) {
        const double f = 0.5 * (s.depth.fx + s.depth.fy);
        if (!(f > 0)) continue;
        double z = 1.5;
        if (centre && s.has_world_from_depth)
            z = (s.world_from_depth.inverse() * *centre).z();
        if (!(z > 0)) z = 1.5;
        footprints.push_back(z / f);
    }
    if (footprints.empty()) return 0.004;
    std::nth_element(footprints.begin(), footprints.begin() + footprints.size() / 2,
                     footprints.end());
    return footprints[footprints.size() / 2];
}

PointCloud fusion_view(const RgbdFrame& frame, int view_id, const VideoFusionOptions& options,
                       const std::optional<Eigen::Vector3d>& centre, Report* report) {
    const Stopwatch watch;
    Report r;
    PointCloud view = frames::depth_to_cloud(frame, options.cloud, nullptr);
    view.view.id = view_id;
    view.view.frame_index = frame.frame_index;
    r["points_in_window"] = view.size();
    if (centre && options.extraction.crop_radius_m > 0)
        frames::crop_to_sphere(view, *centre, options.extraction.crop_radius_m);
    r["points_cropped"] = view.size();
    const double cloud_ms = 1e3 * watch.seconds();
    if (options.clean && view.size() > 0) {
        const Report clean = denoise::remove_distance_outliers(view, options.distance);
        r["removed"] = clean.value("removed", 0);
    }
    r["points"] = view.size();
    if (!view.view.world_from_sensor) {
        view.view.world_from_sensor = frame.world_from_sensor;
    }
    to_world_frame(view);
    r["cloud_ms"] = cloud_ms;
    r["ms"] = 1e3 * watch.seconds();
    if (report) *report = std::move(r);
    return view;
}

PointCloud fuse_views(std::vector<PointCloud>&& views, double voxel_m,
                      const VideoFusionOptions& options, Report* report) {
    RGBD_CHECK(std::isfinite(voxel_m) && voxel_m > 0, "video fusion: voxel must be > 0");
    const Stopwatch watch;
    Report r;
    std::vector<PointCloud> present;
    std::size_t input = 0;
    for (PointCloud& v : views) {
        if (v.empty()) continue;
        RGBD_CHECK(v.view.frame == ViewFrame::kWorld,
                   "video fusion: view " + std::to_string(v.view.id) + " is in its sensor frame");
        input += v.size();
        present.push_back(std::move(v));
    }
    r["views"] = present.size();
    r["input_points"] = input;
    if (present.empty()) {
        if (report) *report = std::move(r);
        PointCloud none;
        none.view.frame = ViewFrame::kWorld;
        return none;
    }
    PointCloud merged;
    if (options.duplicate_radius_voxels > 0 && present.size() > 1) {
        registration::DuplicateOptions dup;
        dup.spacing_m = voxel_m;
        dup.radius_spacing = options.duplicate_radius_voxels;
        dup.max_delta_e = options.max_delta_e;
        dup.noise_model = options.distance.noise_model;
        registration::DuplicateReport dr;
        merged = registration::merge_without_duplicates(std::move(present), dup, &dr);
        r["duplicates"] = dr.duplicates;
        r["replaced"] = dr.replaced;
    } else {
        merged = present.size() == 1 ? std::move(present.front())
                                     : sampling::merge_views(std::move(present));
    }
    r["merge_ms"] = 1e3 * watch.seconds();
    PointCloud fused = sampling::voxel_downsample(merged, voxel_m);
    fused.view.frame = ViewFrame::kWorld;
    fused.view.world_from_sensor.reset();
    r["points"] = fused.size();
    r["ms"] = 1e3 * watch.seconds();
    if (report) *report = std::move(r);
    return fused;
}

}  // namespace rgbd::pipeline
