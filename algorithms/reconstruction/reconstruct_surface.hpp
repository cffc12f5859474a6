// Surface reconstruction of an oriented point cloud into a coloured triangle mesh
// (ALGORITHMS.md §14). Methods: CGAL Poisson (Kazhdan, Bolitho and Hoppe 2006, unscreened,
// solved on a refined Delaunay triangulation, CGAL poisson_surface_reconstruction_delaunay) and
// CGAL advancing-front (Cohen-Steiner and Da 2004, interpolating). Vertex colours by inverse-
// distance weighting of the nearest coloured input points, measured points preferred over
// synthetic ones. See also: algorithms/normals/estimate_normals.hpp (orient normals first),
// algorithms/sampling/voxel_downsample.hpp, CGAL examples poisson_reconstruction.cpp and
// reconstruction_surface_mesh.cpp.
#pragma once

#include <cstddef>
#include <string>

#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::reconstruction {

struct ReconstructionOptions {
    /// "poisson" (watertight, approximating) or "advancing-front" (interpolating, keeps holes).
    std::string method = "poisson";
    /// The input is voxel-downsampled (voxel grown from ŝ) until it has at most this many points,
    /// to bound time and memory; 0 = use every point.
    std::size_t max_points = 60000;
    /// Poisson surface mesher: minimum triangle angle, degrees (CGAL example: 20).
    double sm_angle_deg = 20.0;
    /// Poisson: maximum radius of the surface Delaunay balls, in average spacings (CGAL: 30).
    double sm_radius = 30.0;
    /// Poisson: maximum distance mesh - implicit surface, in average spacings (CGAL: 0.375).
    double sm_distance = 0.375;
    /// Advancing front: radius-ratio bound of candidate triangles (CGAL default 5).
    double af_radius_ratio_bound = 5.0;
    /// Advancing front: maximal dihedral angle deviation, radians (CGAL default 0.52).
    double af_beta = 0.52;
    /// Nearest coloured input points blended per vertex (IDW).
    int color_k = 8;
    /// Only measured (non-`synthetic`) points colour a vertex when one lies within this
    /// multiple of ŝ (ALGORITHMS.md §14: 2 ŝ).
    double color_original_radius = 2.0;
    /// Throws InputError on absurd values or an unknown method.
    void check() const;
};

/// Reconstructs a triangle mesh from a cloud with oriented normals.
/// Output: a valid CGAL Surface_mesh without isolated vertices, garbage collected; with a
/// "v:color" map when the cloud has colours. Poisson output is closed for a closed input.
/// Throws InputError when the cloud has fewer than 100 points, has no normals ("estimate
/// them first"), or has non-finite values; AlgorithmError when CGAL fails (e.g. Poisson solver)
/// or `progress` cancels. Report (if given): method, points_in, points_used, voxel_m,
/// average_spacing_m, vertices, faces, closed, colored, time_s, color_time_s.
Mesh reconstruct_surface(const PointCloud& cloud_with_oriented_normals,
                         const ReconstructionOptions& options, Report* report = nullptr,
                         const Progress& progress = {});

}  // namespace rgbd::reconstruction
