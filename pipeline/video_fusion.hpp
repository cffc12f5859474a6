// Live fusion of one frame set into one coloured point cloud (issue 20, docs/method.md "3D
// video"): the per-view work (what rgbd-cloud + rgbd-clean do: back-projection with colour,
// the world-space crop around the rig's object centre, the adaptive distance-based clean of
// docs/algorithms.md §4, then the rig pose) and the per-set work (colour-based duplicate
// removal, docs/algorithms.md §6.2 step 6, and a voxel grid whose edge is the sensors'
// pixel footprint at the object). The per-view work can run where the frame is made (on a
// node, as LiveScan3D's clients do) or on the hub; both call fusion_view(), so both give the
// same views. No registration: the rig poses are trusted (a video frame has 1/30 s).
#pragma once

#include <optional>
#include <vector>

#include "algorithms/denoise/distance_outliers.hpp"
#include "algorithms/frames/depth_to_cloud.hpp"
#include "algorithms/registration/duplicate_removal.hpp"
#include "io/capture_folder.hpp"
#include "io/video.hpp"
#include "pipeline/stages.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/report.hpp"

namespace rgbd::pipeline {

struct VideoFusionOptions {
    frames::CloudOptions cloud;    ///< back-projection (rgbd-cloud's defaults)
    ExtractionOptions extraction;  ///< crop radius around the object centre
    bool clean = true;             ///< run the distance-based clean per view
    denoise::DistanceOptions distance;
    /// Voxel edge of the fused cloud (m); 0 = video_voxel_m() of the rig.
    double voxel_m = 0.0;
    /// Duplicate removal radius in voxel edges (DuplicateOptions::spacing_m = voxel_m).
    double duplicate_radius_voxels = 1.0;
    double max_delta_e = 15.0;  ///< DuplicateOptions::max_delta_e
    /// Throws InputError for out-of-range values.
    void check() const;
};

/// The voxel edge from the sensors' resolution: the median over the rig's sensors of the
/// depth pixel footprint z / f at the object centre (z = distance sensor-centre, f = mean
/// depth focal length in pixels). Kinect v2 at 1.5 m: 4.1 mm. Without a centre: at 1.5 m.
double video_voxel_m(const io::Rig& rig, const std::optional<Eigen::Vector3d>& centre);

/// Per-view work: depth_to_cloud, crop to the sphere around `centre`, the distance-based
/// clean, then the frame's world_from_sensor (the rig pose). Returns the view in the world
/// frame with colours and view.world_from_sensor set; `report` gets counts and ms.
PointCloud fusion_view(const RgbdFrame& frame, int view_id, const VideoFusionOptions& options,
                       const std::optional<Eigen::Vector3d>& centre, Report* report = nullptr);

/// One view for the hub's fusion: world-frame points and colours, and where its sensor is.
struct FusionView {
    const io::ColoredPoints* points = nullptr;
    Eigen::Vector3d sensor = Eigen::Vector3d::Zero();  ///< the depth camera's position, world
};

/// Per-set work on the hub on flat arrays (what rgbd-capture --video runs): the duplicate
/// removal of docs/algorithms.md §6.2 step 6 and the voxel grid of fuse_views(), with the
/// points of each view first gathered per voxel (edge `voxel_m`, grid anchored at the minimum
/// corner of all points) into cells (centroid, mean colour, mean squared distance to the
/// sensor). View by view in rig order, a cell with an earlier view's live cell within
/// duplicate_radius_voxels voxels (searched in the 3 x 3 x 3 neighbourhood through a hash of
/// the voxels) whose colour agrees (CIE76 <= max_delta_e) is a duplicate and dropped; if the
/// colours disagree, the better observed (nearer its sensor: the smaller sigma_z of §2.3;
/// theta is unknown without normals) stays and the other goes. Output: one point per voxel,
/// the centroid and mean colour of its live cells, in voxel order (deterministic). `report`:
/// views, input_points, points, duplicates, replaced, ms. The same work through
/// merge_without_duplicates + voxel_downsample (fuse_views) took 130-200 ms per set of 8
/// Kinect v2 views of the bunny on a loaded machine, this one 10-25 ms
/// (validation/performance/video_bench.sh reports the hub's CPU per set).
/// @throws InputError for a non-positive voxel or a grid of more than 2^21 voxels per axis.
io::ColoredPoints fuse_points(const std::vector<FusionView>& views, double voxel_m,
                              const VideoFusionOptions& options, Report* report = nullptr);

/// Per-set work: merges world-frame views without duplicates (radius duplicate_radius_voxels
/// x voxel_m, colours within max_delta_e are the same surface, otherwise the better observed
/// point stays) and down-samples to the voxel grid (centroid, mean colour). Views may be
/// empty or missing (a thinned set). `report`: points in, duplicates, out, ms per step.
PointCloud fuse_views(std::vector<PointCloud>&& views, double voxel_m,
                      const VideoFusionOptions& options, Report* report = nullptr);

}  // namespace rgbd::pipeline
