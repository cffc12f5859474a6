// The space the sensors saw empty (docs/algorithms.md §12 and §13 step 5, back to 3D; [M], ours,
// not in the document yet: proposed as §12.4): a point that a fill proposes is invented when a
// sensor had a clear line of sight to it, faced it within the angle at which it measures a surface,
// and measured nothing there: its ray went on to a surface well behind the point, or to the
// background. A real surface there would have been measured by that sensor, so the point lies in
// observed free space (a bulge outside the object, like the base of a bust extended outward by the
// large-hole inpainting). More measurements of the same sensors that are not the object's (the
// floor beside it, which the extraction removed) may be given as evidence: a ray that met them
// behind a point passed through it (outside the object's silhouette whatever the point's normal),
// and they block the view of what lies behind them. Peers: space carving / the visual hull
// (Kutulakos and Seitz, "A theory of shape by space carving", IJCV 2000); KinectFusion's TSDF marks
// the same space empty by ray casting. See also: algorithms/holes/large_holes.hpp (the fills that
// call it).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "algorithms/holes/hole_detection.hpp"

namespace rgbd::holes {

struct FreeSpaceOptions {
    /// Depth-map pixel (angle) as the spacing seen at the points' median distance, in spacings.
    double pixel = 1.5;
    /// A point is in free space when the surface the sensor saw along its ray lies more than
    /// this many spacings behind it.
    double margin = 2.0;
    /// The sensor would have measured a surface facing it within this angle (degrees); a point
    /// whose normal is farther from the line of sight is not tested against that sensor
    /// (grazing surfaces drop out).
    double max_angle_deg = 60.0;
    /// Rays that meet no measured point at all (no point within 2 pixels) and stay inside the
    /// sensor's view of the object (not within `background_border` pixels of the edge of the
    /// bounding box of the points in front of it) saw background: free space too.
    bool background = true;
    int background_border = 3;
    /// Half-width (pixels) of the window around the ray in which no measured point may lie for
    /// the ray to have seen background.
    int background_window = 2;
    void check() const;
};

/// Per-sensor depth maps of a measured cloud: for each sensor, a perspective image around the
/// direction from the sensor to the points' centroid with the nearest depth of the points per
/// pixel (a z-buffer of the whole cloud: what the sensor's rays meet first).
class FreeSpace {
public:
    /// `points` are the measured surface in the sensors' frame, `spacing_m` its point spacing
    /// (metres). No sensors: nothing is ever free space.
    /// `evidence` (optional, world frame): more measurements of the same sensors that are not
    /// the object's (the floor beside it, what the extraction removed). They enter the maps'
    /// nearest depths only: the maps' scale, their placement and the background test's frame
    /// (the bounding box of `points`) are those of `points` alone, each map grown by whole
    /// pixels to hold them (to at most 4 times its pixels).
    FreeSpace(const std::vector<Eigen::Vector3d>& points, const std::vector<SensorView>& sensors,
              double spacing_m, const FreeSpaceOptions& options,
              const std::vector<Eigen::Vector3d>& evidence = {});

    /// Index of the first sensor that saw the point `p` (unit normal `n`, outward) as empty
    /// space: p in front of it (and in its image when its intrinsics are known), and either n
    /// within max_angle_deg of the line of sight and every measured point within the 3 x 3
    /// pixels around p's ray behind p by more than `margin`, or (whatever n) no measured point
    /// within 5 x 5 pixels: outside the object's silhouette, see `background`. -1 when
    /// no sensor did (occluded, grazing, outside every view, or on the measured surface).
    int seen_empty(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const;

    /// How many sensors saw the point `p` (unit normal `n`) as empty space, by the test of
    /// seen_empty(): agreement of several sensors is the stronger evidence.
    int count_seen_empty(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const;

private:
    /// seen_empty() (count false: the first sensor or -1), count_seen_empty() (count true).
    int scan(const Eigen::Vector3d& p, const Eigen::Vector3d& n, bool count) const;

    struct Map {
        Eigen::Vector3d centre, forward, right, down;
        double focal = 0;  ///< pixels per unit of tan(angle)
        int cols = 0, rows = 0;
        /// The pixels [col0, col0 + inner_cols) x [row0, row0 + inner_rows) frame the points'
        /// own bounding box (the background test's border is counted from it).
        int col0 = 0, row0 = 0, inner_cols = 0, inner_rows = 0;
        double u0 = 0, v0 = 0;        ///< image-plane coordinates (tan) of pixel (0, 0)'s corner
        std::vector<float> nearest;   ///< depth along forward per pixel; +inf = none
        std::vector<float> evidence;  ///< the same of the evidence; empty without any
        SensorView sensor;
        Pose sensor_from_world;  ///< sensor.world_from_sensor's inverse, for the frustum test
    };
    std::vector<Map> maps_;
    FreeSpaceOptions options_;
    double spacing_ = 0;
};

}  // namespace rgbd::holes
