// Statistical and radius outlier removal: the classic baselines of docs/algorithms.md §4 / §8,
// reproducing the exact rules of the peers so that side-by-side runs are comparable.
//
// Sources: Rusu et al., "Towards 3D Point cloud based object maps for household environments"
// (RAS 2008), as implemented by PCL 1.13 `StatisticalOutlierRemoval` / `RadiusOutlierRemoval`
// and Open3D 0.16 `remove_statistical_outlier` / `remove_radius_outlier`. The quirks of both
// are documented at each option below (checked against the
// PCL source and by running python3-open3d 0.16.1).
// See also: CGAL `remove_outliers` (Point_set_processing_3), algorithms/internal/kd_tree.hpp.
#pragma once

#include <cstdint>

#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::denoise {

/// Which peer's exact rule to follow.
enum class OutlierConvention {
    /// Open3D 0.16. Statistical: the k neighbours include the point itself (a zero distance);
    /// d_i = mean distance; mean and std (Bessel) over the points with d_i > 0; keep i iff
    /// 0 < d_i < mean + ratio * std (strictly; a point whose k neighbours are all duplicates,
    /// d_i = 0, is removed, as Open3D does). Radius: keep iff #{j : |p_j - p_i| < r} (self
    /// included, strict <) > min_points.
    kOpen3d,
    /// PCL 1.13. Statistical: k neighbours excluding the point itself (k + 1 searched, the
    /// first dropped); d_i as float; mean, std (Bessel, one-pass formula) over all points;
    /// keep iff d_i <= mean + ratio * std. Radius: keep iff #{j : |p_j - p_i| <= r} (self
    /// included) > min_points.
    kPcl,
};

/// Options of remove_statistical_outliers().
struct StatisticalOptions {
    /// Neighbours per point (Open3D nb_neighbors, PCL mean_k). Clamped to the cloud size (see
    /// the report's k_clamped).
    int k = 20;
    /// Threshold = mean + std_ratio * std of the per-point mean distances (PCL std_mul).
    double std_ratio = 2.0;
    OutlierConvention convention = OutlierConvention::kOpen3d;
    /// Set the `noise` flag to 1 on outliers instead of deleting them.
    bool mark = false;

    /// Throws InputError for k < 1 or > 10000, or std_ratio negative / not finite.
    void check() const;
};

/// Options of remove_radius_outliers().
struct RadiusOptions {
    /// A point is kept when its neighbour count within the radius, itself included, exceeds
    /// min_points (Open3D nb_points, PCL min_pts_radius).
    int min_points = 16;
    /// Search radius in metres; 0 = radius_spacing_factor * s_hat (robust spacing).
    double radius_m = 0.0;
    /// Radius as a multiple of the robust spacing s_hat (median nearest-neighbour distance of
    /// a fixed-seed sample of <= 10 000 points, docs/algorithms.md, notation,
    /// rgbd::sampling::robust_spacing). Used when radius_m == 0.
    double radius_spacing_factor = 4.0;
    /// Seed of the s_hat sample.
    std::uint64_t seed = 42;
    OutlierConvention convention = OutlierConvention::kOpen3d;
    /// Set the `noise` flag to 1 on outliers instead of deleting them.
    bool mark = false;

    /// Throws InputError for min_points < 0, a negative radius or factor, or non-finite values.
    void check() const;
};

/// Statistical outlier removal (SOR) in place.
///
/// @param cloud    any cloud; every coordinate must be finite. Deleting keeps all properties
///                 aligned (Point_set_3 remove + collect_garbage), order preserved.
/// @param options  see StatisticalOptions.
/// @param progress called with the fraction done; returning false cancels (cloud unchanged,
///                 report "cancelled": true).
/// @return report: method, convention, k (resolved), k_requested, k_clamped, std_ratio,
///         mean_distance_m, std_distance_m, threshold_m, input_points, removed (or marked),
///         time_s.
/// @throws InputError naming the view for a non-finite point.
Report remove_statistical_outliers(PointCloud& cloud, const StatisticalOptions& options,
                                   const Progress& progress = {});

/// Radius outlier removal in place (rule per convention, see OutlierConvention).
/// @return report: method, convention, min_points, radius_m (resolved), spacing_m (when
///         derived), input_points, removed (or marked), time_s.
/// @throws InputError naming the view for a non-finite point.
Report remove_radius_outliers(PointCloud& cloud, const RadiusOptions& options,
                              const Progress& progress = {});

}  // namespace rgbd::denoise
