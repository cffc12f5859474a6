// Adaptive density-based noise removal after alignment (docs/algorithms.md §8): floating clusters,
// sparse stragglers and halos between views, judged against the density the sensors should
// have produced at each point rather than one global threshold.
//
// Measured density [M]: rho_i = (points of all views within r of p_i, itself excluded) /
// (pi r^2), r = sqrt(k / pi) ŝ (areal density of a surface through p_i), counted on a grid of
// side r; the local reference uses rho_i = k / (pi d_k^2), d_k = distance to the k-th nearest.
// Expected density [M] ("sensors" reference): every view v with intrinsics and a pose that
// should see p_i contributes cos(theta_v) / s_d_v(z_v)^2, z_v = depth of p_i in camera v,
// s_d = z / f, theta_v = angle between the ray and the normal (the views' own, else the PCA
// normal of the neighbourhood), not clamped: a view grazing the surface adds almost nothing
// (clamping cos to >= cos(theta_max) flagged sparse grazing surface: on the rgbd-synth rings
// geometric F1 0.929 -> 0.935 and 0.943 -> 0.945 without it, measure_denoise.py).
// v should see p_i when p_i projects inside v's image and is not
// occluded by v's own depth map (3 x 3 window, tolerance dz_max(z) of §4): on v's surface, in
// front of it (free space: v would have measured it) or where v has no return at all.
// Fallback [R] ("local" reference, §8 step 3): the median measured density of the k_ref
// nearest neighbours, for clouds without per-view cameras (merged or unorganised clouds).
// Remove p_i when rho_i < beta * expected_i.
// Consensus test (sensors reference): a flying pixel d off a surface keeps the surface cap of
// its counting sphere, rho / expected ~ 1 - (d / r)^2 for a plane, so beta = 0.1 only catches
// d > 0.95 r (~9.5 mm on the 8-Kinect rings); the misses were flying pixels 7-10 mm off.
// Remove p_i also when all three hold: (a) rho_i < consensus_ratio * expected_i; (b) its own
// view's ray meets its normal steeper than theta_max (it sits on a depth discontinuity of that
// view, where a real surface is not measured); (c) it lies more than consensus_sigmas *
// sigma_z(z_own) off the plane of the OTHER views' points within consensus_radius * r (PCA,
// trimmed twice to 3 sigma_z; at least 6 points, else no verdict). Each cue alone flags
// hundreds of surface points (silhouettes, creases, misaligned patches; on the rings an
// own-view grid residual and a free-space test did too); together they veto each other's.
// Measured (measure_denoise.py, merged rows, geometric F1 max_planck / wreath): 0.935 / 0.945
// without it, 0.961 / 0.953 with (0.5, 4.5 sigma, 1.5 r, theta_max 75); >= 0.950 on both for
// consensus_ratio 0.4-0.6, consensus_sigmas 4-5, theta_max 70-75 (78: 0.956 / 0.951); a
// smaller k instead (8-16, any beta) never passed 0.945 on either. Fresh captures (--seed 7):
// 0.926 / 0.946 -> 0.945 / 0.954 (the "known to 1 mm" oracle there: 0.955 / 0.963).
// About 0.3% of the points are candidates: the test takes ~2 ms of the 0.1 s.
//
// Cluster pass (§8 step 5): components of the eps = cluster_spacing * s_hat graph over the
// survivors; keep the largest and those with at least min_cluster_fraction of the survivors.
// Peers: Open3D remove_radius_outlier, remove_statistical_outlier, cluster_dbscan; PCL
// RadiusOutlierRemoval + EuclideanClusterExtraction; CGAL remove_outliers.
// See also: distance_outliers.hpp (before alignment), sensor_noise.hpp.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "algorithms/denoise/sensor_noise.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::denoise {

/// Where the expected density comes from.
enum class DensityReference {
    kAuto,     ///< kSensors when every non-empty view has intrinsics and a pose, else kLocal
    kSensors,  ///< from the views' cameras (throws InputError when a view lacks them)
    kLocal,    ///< median measured density of the k_ref nearest neighbours
};

inline constexpr EnumName<DensityReference> kDensityReferenceNames[] = {
    {DensityReference::kAuto, "auto"},
    {DensityReference::kSensors, "sensors"},
    {DensityReference::kLocal, "local"}};

/// The reference named "auto", "sensors" or "local" (rgbd-clean --reference); nullopt for any
/// other name.
inline std::optional<DensityReference> density_reference_of(std::string_view name) {
    return value_of(kDensityReferenceNames, name);
}

/// Options of remove_density_outliers().
struct DensityOptions {
    DensityReference reference = DensityReference::kAuto;
    /// Sensor noise model for the occlusion tolerance dz_max(z) (§2.3, §4).
    NoiseModel noise_model = NoiseModel::kKinectV2;
    /// Steepest incidence of a real surface, degrees (occlusion tolerance dz_max).
    double theta_max_deg = 75.0;
    /// Neighbourhood of the measured density. Sensors reference: the disc of radius
    /// sqrt(k / pi) ŝ, which a frontal surface seen by one sensor fills with about k points
    /// (ŝ: one view's robust spacing); local reference: the k nearest other points.
    int k = 20;
    /// Neighbours of the local reference density (kLocal).
    int k_ref = 64;
    /// Keep a point when measured >= beta * expected density (sensors reference; measured
    /// on rgbd-synth rings: geometric F1 flat within 0.005 for beta 0.08-0.12, k 20-32).
    double beta = 0.1;
    /// The same for the local reference.
    double beta_local = 0.2;
    /// Consensus test (sensors reference, see the file comment): candidates have less than
    /// this share of their expected density (0 = no consensus test).
    double consensus_ratio = 0.5;
    /// Consensus test: flag a candidate farther than this many sigma_z (its own view's noise at
    /// its depth) from the plane of the other views' points.
    double consensus_sigmas = 4.5;
    /// Consensus test: those points are taken within this multiple of the counting radius
    /// sqrt(k / pi) ŝ (at most 2: the counting grid's 5 x 5 x 5 cells).
    double consensus_radius = 1.5;
    /// Cluster pass: link distance as a multiple of the robust spacing s_hat (0 = no pass).
    double cluster_spacing = 3.0;
    /// Cluster pass: components smaller than this share of the survivors go (the largest stays).
    double min_cluster_fraction = 0.005;
    /// Sensors reference: judge super-resolved points (flagged synthetic) wholly on their own.
    /// By default, in a view that has measured points, a super-resolved point is judged on its
    /// own neighbour count against its parent's expected density (the measured point of its
    /// view it was made from: the one with its pixel, else the nearest; it lies within a depth
    /// pixel of it), and takes its parent's verdict in the cluster pass, which links the measured
    /// survivors at their own spacing: the same verdicts within a few points (the 10-view ring:
    /// ...), for a fraction of the time (the expected density's sums over the cameras and the
    /// cluster graph over 8 times the measured points after an 8-neighbour upsampling).
    bool judge_synthetic = false;
    /// Seed of the s_hat sample.
    std::uint64_t seed = 42;
    /// Set the `noise` flag to 1 on outliers instead of deleting them.
    bool mark = false;

    /// Throws InputError for out-of-range values.
    void check() const;
};

/// Removes (or marks) density outliers of a set of aligned views in place, judged over all
/// views together; each view keeps its own surviving points and metadata.
///
/// @param views  world-frame views, or sensor-frame views with world_from_sensor (a single
///               view without a pose is used in its own frame). Every coordinate finite.
/// @return report: method, reference, spacing_m, cluster_eps_m, input_points,
///         synthetic_followers (points with a parent, without judge_synthetic), density
///         (removed by the density test), consensus (by the consensus test) and
///         consensus_candidates (points it examined), cluster (removed by the cluster pass),
///         clusters, removed (or marked), per-view counts ("views"), time_s.
/// @throws InputError naming the view for a non-finite coordinate, a missing pose among several
///         views, or missing cameras with DensityReference::kSensors.
Report remove_density_outliers(std::vector<PointCloud>& views, const DensityOptions& options,
                               const Progress& progress = {});

}  // namespace rgbd::denoise
