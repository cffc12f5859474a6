// The cut an object stood on, for the watertight closure (docs/algorithms.md §14; internal to
// algorithms/reconstruction, not installed): the planes of boundary loops (PCA, refitted robustly
// without the vertices far off them), the cut loops (a planar loop at a crease; with the up
// direction, the loops at the bottom of the mesh), the plane through them and the walls carried
// down to it. close_holes() (mesh_finishing.cpp) gives such loops a flat base.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <utility>
#include <vector>

#include "toolkit/mesh.hpp"

namespace rgbd::reconstruction::internal {

/// Best-fit plane of a boundary loop's vertices (PCA).
struct LoopPlane {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
    double rms = 0;     ///< RMS distance of the loop's vertices to the plane
    double radius = 0;  ///< farthest loop vertex from the centre
    std::size_t size = 0;
    /// The same plane refitted without the vertices far off it (a gap in the seen rim that
    /// climbs up the side, noise at a grazing edge): 3 rounds keeping residuals within 2.5
    /// robust sigmas (1.4826 median absolute deviation) of the median.
    Eigen::Vector3d robust_centre = Eigen::Vector3d::Zero();
    Eigen::Vector3d robust_normal = Eigen::Vector3d::UnitZ();
    double robust_rms = 0;  ///< RMS distance of the kept vertices to the robust plane
};

/// The vertices of the boundary loop of border halfedge h, in loop order.
std::vector<Eigen::Vector3d> loop_points(const Mesh& mesh, Mesh::Halfedge_index h);

/// The loop's plane (LoopPlane: its PCA plane, then refitted 3 times without the vertices
/// beyond 2.5 robust sigmas of the median residual, while at least 8 remain).
LoopPlane fit_loop_plane(const std::vector<Eigen::Vector3d>& loop);
LoopPlane fit_loop_plane(const Mesh& mesh, Mesh::Halfedge_index h);

/// Without an up direction: a loop that is planar and meets the surface around it at a crease
/// (the faces along it are steep to its plane, as at the cut base of a bust) is a cut. The
/// crease test also accepts a flat crown above vertical sides, hence the `up` variant below.
bool is_crease_cut(const Mesh& mesh, Mesh::Halfedge_index h, const LoopPlane& plane);

/// The plane the object stood on: a point on it and its downward unit normal (within 30 degrees
/// of -up).
struct SupportPlane {
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
};

/// The loops' robust plane moved down to their deep quintile. The rim's lowest vertices are its
/// noisiest (grazing views of the bottom edge) and its highest climb into gaps of the seen rim:
/// the cut goes through the deep quintile, neither the deepest vertex nor the median. Measured on
/// the validation busts (measure_mesh.py, F@2mm / invented with --watertight): quantile 0.75:
/// 0.962 / 0.23% (Max Planck), 0.964 / 0.64% (wreath); 0.8: 0.963 / 0.23%, 0.962 / 0.68%; 0.9:
/// 0.972 / 0.26%, 0.953 / 0.65%.
SupportPlane support_plane(const std::vector<Eigen::Vector3d>& rim, const Eigen::Vector3d& up);

/// Extends the loop of border halfedge h straight down (along -up) to the support plane.
/// Vertices already below it drop a twentieth of a mean edge, so no wall triangle is degenerate.
/// Two triangles per loop edge. Returns a border halfedge of the new loop (planar but for those
/// few vertices). `walls` (optional) receives each wall's (top, bottom) vertices in loop order.
Mesh::Halfedge_index extrude_to_support(
    Mesh& mesh, Mesh::Halfedge_index h, const SupportPlane& support, const Eigen::Vector3d& up,
    std::vector<std::pair<Mesh::Vertex_index, Mesh::Vertex_index>>* walls = nullptr);

/// With up: the loops that make up the cut the object stood on. The support cuts
/// (is_support_cut) and every other loop of at least 8 edges that lies at the bottom: within
/// 30 degrees of horizontal (robustly) and reaching down to the support cuts' rim, so a rim split
/// into several loops (a thin bridge of faces across the base, a pinched rim) or a ragged part
/// of it gets the same base. The result flags them in `borders` order; `support` receives the
/// plane through all their vertices.
std::vector<char> support_loops(const Mesh& mesh, const std::vector<Mesh::Halfedge_index>& borders,
                                const Eigen::Vector3d& up, double low, double high,
                                SupportPlane& support, std::vector<Eigen::Vector3d>* rim_out);

}  // namespace rgbd::reconstruction::internal
