// The measurements of the views' own depth frames around the subject, as evidence of the space
// the sensors saw empty (issue 35, "a closed mesh that invents nothing the sensors contradict";
// docs/algorithms.md §14). The object extraction removes the ground, walls and clutter from the
// views, and the cleaning removes outliers, so the points that reach the mesh stage are the
// subject's alone; yet a ray that hit the floor beside a bust's base passed through empty space
// on its way. Every view names its depth frame (rgbd:view.source, with rgbd:view.sensor and
// rgbd:view.frame_index): this reads it again from its capture, back-projects every valid pixel
// and moves it by the view's current (aligned) pose, so that rgbd-mesh down a pipe and
// rgbd-reconstruct see the same evidence. Peers: KinectFusion's TSDF and space carving take
// every measured depth as free space in front of it.
// See also: algorithms/holes/free_space.hpp (the maps the points go into),
// algorithms/reconstruction/reconstruct_surface.hpp (ReconstructionOptions::evidence_points).
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <vector>

#include "toolkit/point_cloud.hpp"
#include "toolkit/report.hpp"

namespace rgbd::pipeline {

/// What source_measurements() found.
struct SourceMeasurements {
    std::vector<Eigen::Vector3d> points;  ///< world frame, metres
    std::size_t frames_read = 0;          ///< views whose frame was read
    std::size_t frames_missing = 0;       ///< views with a source that could not be read
    std::string note;                     ///< the first reason a source could not be read
    Report to_json() const;
};

/// The capture folder a depth frame's path lies in: the nearest of its parent folders (up to 4
/// levels) that io::open_capture opens and whose frames include `sensor_id`. Empty when none.
std::string capture_root_of(const std::string& source, const std::string& sensor_id);

/// Every valid depth pixel of each view's source frame (views with a source, a sensor, a
/// pose and depth intrinsics; others, such as the fill's synthetic points, are skipped),
/// back-projected with the frame's intrinsics and distortion and moved into the world frame by
/// the view's world_from_sensor; kept when inside `box` (world frame) and, with `ground_band`
/// > 0, within ground_band times the view's cut margin of the ground plane the view carries
/// (segment::view_ground: what the extraction removed as the ground, and the subject's own
/// lowest band below the cut; a view without a ground plane then gives nothing). A view whose
/// source cannot be read (the capture moved, another layout) is counted in frames_missing and
/// skipped: the evidence is then only the views' own points, never an error. Views are read in
/// parallel.
SourceMeasurements source_measurements(const std::vector<PointCloud>& views,
                                       const Eigen::AlignedBox3d& box, double ground_band = 0.0);

}  // namespace rgbd::pipeline
