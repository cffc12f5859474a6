// upsample_view: colour-guided 3D super-resolution of one organised view, 4- and 8-neighbour
// (docs/algorithms.md §5).
//
// The colour camera has about 3x the depth camera's focal length (Kinect v2: 1081.37 / 365.5
// = 2.96), so one depth pixel covers about 3x3 colour pixels. Algorithm A (default) adds one
// point per colour pixel around the colour pixel a depth point maps to: its 4 (N, S, E, W) or
// 8 neighbours. The new point lies on the colour camera's ray through that colour pixel; its
// depth along the ray is a joint bilateral average (Kopf et al., "Joint bilateral
// upsampling", SIGGRAPH 2007) of the intersections of the ray with the local planes through
// the surrounding depth samples (3x3 depth neighbourhood, shared normal from the depth grid),
// weighted by the colour-pixel distance (spatial) and by the similarity of the new pixel's
// colour to each sample's colour (range). A depth pixel next to a depth discontinuity
// (|dz| > dz_max of §4) gets no new points, so nothing is ever placed in the gap; a colour
// pixel belongs to the depth pixel whose projection is nearest (no duplicates). Colour of a
// new point = the colour pixel itself (exact pixel; bilinear when the colour resolution is
// below 2.25x the depth's, then the steps are sub-pixel and the colour carries no new detail).
// Algorithm B (option) adds midpoints between grid neighbours (E, S; + SE, SW for 8).
//
// New points: flag prop::kSynthetic = 1, flag prop::kColourPixel = 1 (Algorithm A: their colour
// is the colour camera's at their position), `pixel` = the parent depth pixel, `confidence` =
// parent confidence x the mean colour (range) weight of the bilateral average (Algorithm B:
// 0.8 x the smaller parent confidence), normal = the local plane normal when the view has
// normals. The view's metadata alone does not give the colour image: the caller loads the
// RgbdFrame of the view (rgbd-upsample finds it through the capture folder).
// See also: CGAL edge_aware_upsample_point_set, PCL MovingLeastSquares upsampling (peers,
// validation/quality/upsample/).
#pragma once

#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"
#include "toolkit/rgbd_frame.hpp"

namespace rgbd::upsample {

/// Algorithm A (colour pixels around each depth pixel) or B (midpoints on the depth grid).
enum class UpsampleMethod { kColourPixels, kMidpoints };

/// Options of upsample_view().
struct UpsampleOptions {
    /// 4 (N, S, E, W) or 8 neighbours.
    int neighbors = 8;
    UpsampleMethod method = UpsampleMethod::kColourPixels;
    /// Spatial sigma of the joint bilateral weight, in depth-pixel footprints (x rho colour
    /// pixels, rho = f_colour / f_depth).
    double sigma_spatial = 1.0;
    /// Range sigma of the joint bilateral weight: mean absolute RGB difference, 8-bit levels.
    double sigma_color = 24.0;
    /// Discontinuity gate dz_max(z) = s_d(z) tan(theta_max) + sigma_factor sigma_z(z) (§4),
    /// s_d = z / f_depth, sigma_z(z) = 0.0015 (z / 1.5)^2 m.
    double theta_max_deg = 75.0;
    double sigma_factor = 3.0;
    /// Reject a new point when its colour ray meets the local plane at more than this angle
    /// from the normal (grazing).
    double grazing_max_deg = 80.0;
    /// Reject a new point farther than this many depth-pixel footprints s_d from its parent.
    double max_offset_factor = 1.5;

    /// Throws InputError on invalid values.
    void check() const;
};

/// Adds super-resolved points to `cloud` (in place; the original points keep their order and
/// come first). `cloud` must be organised (view grid + `pixel`), in the sensor frame or in the
/// world frame with a world_from_sensor pose; `frame` must carry the colour image with its
/// intrinsics and color_from_depth, and the depth intrinsics of the view's grid. Points already
/// flagged synthetic are not parents. Deterministic for any thread count.
///
/// @throws InputError naming the view (and frame source) for a view without grid or pixel
/// map, a frame without colour image, or sizes that do not match.
/// @return report: method, neighbors, rho, parents, gated (discontinuity), new points,
/// rejections by reason, points_before/after, time_s and its splits time_prepare_s (point
/// table), time_children_s (new points), time_append_s (writing them into the point set).
Report upsample_view(PointCloud& cloud, const RgbdFrame& frame, const UpsampleOptions& options,
                     const Progress& progress = {});

}  // namespace rgbd::upsample
