// Edge-aware depth smoothing of one organised view along the pixel rays [M] (ours; an option of
// the per-view cleaning, `rgbd-clean --smooth`): noise removal that moves points instead of
// deleting them. Measured in validation/quality/denoise.
//
// For every valid pixel i, the neighbours j of its (2h + 1)^2 window (itself included) whose
// depth is within gate_sigmas sigma_z(z_i) of z_i (the same surface: the gate stops at depth
// edges and flying pixels) are fitted with a plane in inverse depth, 1/z = a + b du + c dv
// (exact for a plane seen by a pinhole camera, du, dv = pixel offsets), least squares; the
// point moves along its own ray to z' = 1 / a. Fewer than min_support gated pixels: unchanged;
// gated pixels on one line (degenerate plane): the mean of 1/z instead; a fit that would move
// the point by more than gate_sigmas sigma_z(z_i): unchanged. Points flagged as noise (--mark)
// are neither moved nor used. The pixel, colour and every other property stay; normals are
// not re-estimated (the change is below the noise).
// Known answers (tests/algorithms/denoise/depth_smoothing_test.cpp): a noisy tilted plane,
// a depth step between two planes (no point crosses to the other side), flagged points.
// Measured: rgbd-synth rings (Kinect v2 model), surface points' mean distance to the true
// surface 1.01 -> 0.46 mm (Max Planck), 1.05 -> 0.63 mm (wreath); Augmented ICL-NUIM
// livingroom1 (PrimeSense model, noisy vs clean depth, measure_livingroom.py): mean distance
// 8.71 -> 8.16 mm with 99.99% of the points kept (Open3D SOR 8.46 mm after deleting 4.5%).
// Opt-in, not in the default pipeline: downstream it is mixed (measure_mesh.py --clean-args
// --smooth, --watertight, d8: Max Planck F@2mm 0.973 -> 0.976, Chamfer 0.55 -> 0.42 mm; wreath
// F 0.962 -> 0.949, Chamfer 0.66 -> 0.69 mm; why the wreath loses is not analysed yet).
// See also: distance_outliers.hpp (the removal that runs first), sensor_noise.hpp.
#pragma once

#include "algorithms/denoise/sensor_noise.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::denoise {

/// Options of smooth_depth().
struct SmoothOptions {
    /// Sensor noise model for the gate sigma_z(z).
    NoiseModel noise_model = NoiseModel::kKinectV2;
    /// Half size h of the (2h + 1)^2 window.
    int half_window = 2;
    /// A neighbour is on the same surface when its depth is within this many sigma_z(z_i).
    double gate_sigmas = 3.0;
    /// Gated pixels (the point itself included) needed to move a point.
    int min_support = 6;

    /// Throws InputError for out-of-range values (half_window in [1, 7], gate_sigmas in
    /// (0, 100], min_support in [1, (2 half_window + 1)^2]).
    void check() const;
};

/// Smooths the depths of one organised view in place, each point moving along its pixel ray.
///
/// @param cloud  an organised view (view.has_grid() and the `pixel` property), sensor frame or
///               world frame with view.world_from_sensor. Empty views pass unchanged.
/// @return report: method ("smooth"), noise_model, input_points, moved, unchanged (too little
///         support or a fit beyond the gate), mean_shift_mm, time_s.
/// @throws InputError naming the view: no grid or no `pixel` property (the message says that
///         smoothing works on organised views, before alignment), a non-finite coordinate, a
///         world-frame view without a pose.
Report smooth_depth(PointCloud& cloud, const SmoothOptions& options, const Progress& progress = {});

}  // namespace rgbd::denoise
