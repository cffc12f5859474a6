// Adaptive distance-based noise removal on one organised view, before alignment (ALGORITHMS.md
// §4): flying pixels, speckles and isolated outliers, with every threshold scaled by the depth
// (pixel footprint s_d(z) = z / f) and the sensor noise model sigma_z(z) of §2.3.
//
// Pass A [M], on the pixel grid (ours; measured in validation/quality/denoise):
//  1. window support: a real surface at incidence <= theta_max puts a neighbour at pixel
//     offset o within |o| s_d(z) / cos(theta_max) + 3 sigma_z(z) in 3D; a point with fewer
//     than c_min such neighbours in its 5 x 5 window is flying (ALGORITHMS.md §4 step 2 counts
//     depth jumps in 3 x 3 instead: it loses grazing surface next to dropouts);
//  2. line support where the 5 x 5 window is dense (>= dense_min valid pixels): p must continue
//     a straight depth line along one of the 4 grid axes (interpolated between both sides or
//     extrapolated from one, within line_sigmas sigma_z of the second difference). Flying
//     pixels between two surfaces near each other pass test 1 but not this one;
//  3. speckles: connected grid components (|dz| <= dz_max(z)) smaller than n_speckle pixels
//     (the largest component is never removed).
// Pass B [R] (off by default: it adds a kd-tree and nothing measurable on rgbd-synth rings):
// depth-normalised kNN statistic r_i = dbar_i / s_d(z_i) over the survivors; remove
// r_i > max(median + alpha sigma_rob, median / cos(theta_max)).
// Peers: Open3D remove_statistical_outlier / remove_radius_outlier, PCL
// StatisticalOutlierRemoval, libfreenect2's edge-aware filter (statistical_outliers.hpp).
// See also: sensor_noise.hpp, density_outliers.hpp (after alignment).
#pragma once

#include "algorithms/denoise/sensor_noise.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::denoise {

/// Options of remove_distance_outliers().
struct DistanceOptions {
    /// Sensor noise model for sigma_z(z) (§2.3).
    NoiseModel noise_model = NoiseModel::kKinectV2;
    /// Steepest incidence angle of a real surface, degrees (window support radius, dz_max and
    /// Pass B's floor).
    double theta_max_deg = 70.0;
    /// Pass A: a pixel needs at least this many supporting neighbours in its 5 x 5 window.
    int c_min = 2;
    /// Pass A: line-support tolerance in sigma_z (0 = no line test).
    double line_sigmas = 4.0;
    /// Pass A: the line test applies when at least this many of the 24 window pixels are valid.
    int dense_min = 20;
    /// Pass A: grid components with fewer pixels are speckles (0 = no speckle test).
    int n_speckle = 20;
    /// Pass B: neighbours per point (the point itself excluded).
    int k = 16;
    /// Pass B: robust standard deviations above the median of r that are kept.
    double alpha = 3.0;
    bool pass_a = true;
    bool pass_b = false;
    /// Set the `noise` flag to 1 on outliers instead of deleting them.
    bool mark = false;

    /// Throws InputError for out-of-range values (theta_max in (0, 89], c_min in [0, 24],
    /// line_sigmas in [0, 1000], dense_min in [0, 24], n_speckle in [0, 10^7], k in [1, 1000],
    /// alpha in [0, 1000]).
    void check() const;
};

/// Removes (or marks) flying pixels, speckles and outliers of one organised view in place.
///
/// @param cloud  an organised view: view.has_grid() and the `pixel` property. Sensor-frame
///               coordinates, or world frame with view.world_from_sensor. The focal length is
///               view.intrinsics (mean of fx, fy) or, without intrinsics, estimated from the
///               points of horizontally adjacent pixels. Empty views pass unchanged.
/// @return report: method, noise_model, focal_px, input_points, flying, speckle, statistical,
///         removed (or marked), r_median, r_sigma_rob, r_threshold, components, time_s.
/// @throws InputError naming the view: no grid (the message suggests --density), no `pixel`
///         property, a non-finite coordinate, a world-frame view without a pose.
Report remove_distance_outliers(PointCloud& cloud, const DistanceOptions& options,
                                const Progress& progress = {});

}  // namespace rgbd::denoise
