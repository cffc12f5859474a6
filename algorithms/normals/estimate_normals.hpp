// Normal estimation by PCA over the k nearest neighbours, with orientation towards the sensor,
// by a minimum spanning tree, or outward from the centroid (docs/algorithms.md §9 steps 1-3).
// Sources: Hoppe et al. 1992 "Surface reconstruction from unorganized points" (PCA normals,
// MST orientation); CGAL pca_estimate_normals / mst_orient_normals; Open3D estimate_normals.
// See also: algorithms/sampling/robust_spacing.hpp, algorithms/registration/icp.hpp.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <vector>

#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::normals {

/// How normals are given a sign.
enum class NormalOrientation {
    kAuto,     ///< kSensor when a sensor position is known (see below), else kMst
    kSensor,   ///< towards the sensor centre (InputError when unknown)
    kMst,      ///< consistent propagation along a Riemannian MST (CGAL mst_orient_normals)
    kOutward,  ///< away from the centroid of the cloud (convex-ish, closed objects)
    kNone,     ///< leave the PCA sign (arbitrary)
};

struct NormalOptions {
    /// Neighbours used for PCA, the point itself included (>= 3).
    int k = 24;
    /// Orientation rule. Sensor centre: the origin for a sensor-frame view; the translation of
    /// view.world_from_sensor for a world-frame view; or, per point, `sensor_centres` below.
    NormalOrientation orientation = NormalOrientation::kAuto;
    /// Merged clouds: sensor centre (in the cloud's frame) per source view id; points whose
    /// `view` property is listed are oriented towards that centre (used by kAuto / kSensor).
    std::map<int, Eigen::Vector3d> sensor_centres;
    /// Organised views (sensor frame, a pixel grid and a pixel per point, as rgbd-cloud and
    /// super-resolution make them) take each depth pixel's k nearest points from the window of
    /// pixels around it (one PCA per pixel) instead of a kd-tree over the whole view; false:
    /// always the kd-tree.
    bool pixel_grid = true;
    /// Neighbours of the MST graph for kMst (CGAL's default is 18).
    int mst_k = 18;

    /// Throws InputError on absurd values.
    void check() const;
};

/// Estimates a unit normal per point (adds the normal map if absent, overwrites otherwise).
/// Normal = eigenvector of the smallest eigenvalue of the covariance of the k nearest
/// neighbours; TBB-parallel and identical for any thread count (kMst is sequential).
/// Preconditions: at least 3 points, finite coordinates (InputError naming the view otherwise).
/// Report: k, orientation used, points, flipped count, unoriented count (kMst leftovers are
/// then oriented outward), degenerate neighbourhoods, time_s. Cancelled by `progress`:
/// throws AlgorithmError("cancelled").
/// `neighbours`: when given and the neighbours came from the kd-tree (not the pixel window),
/// every point's min(k, points) nearest, nearest first (the point itself among them), point
/// after point in the cloud's order; left empty otherwise. Callers that need fewer nearest
/// neighbours of the same points take the first ones (the alignment's intensity gradients).
Report estimate_normals(PointCloud& cloud, const NormalOptions& options,
                        const Progress& progress = {},
                        std::vector<std::uint32_t>* neighbours = nullptr);

/// Name of an orientation as used in reports and CLI options ("auto", "sensor", "mst",
/// "outward", "none").
const char* to_string(NormalOrientation orientation);

}  // namespace rgbd::normals
