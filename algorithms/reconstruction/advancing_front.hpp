// The advancing front of the "front" and "advancing-front" surface reconstruction methods
// (docs/algorithms.md §14): CGAL's Advancing_front_surface_reconstruction (Cohen-Steiner and Da,
// "A greedy Delaunay-based surface reconstruction algorithm", 2004) over the points' Delaunay
// triangulation, with the filtered front's candidate test, a faster seed search, and ties broken
// by point index so that the same points give the same mesh in every process. Internal to
// algorithms/reconstruction; CGAL's templates for it live in advancing_front.cpp only.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "toolkit/mesh.hpp"

namespace rgbd::reconstruction::internal {

/// The filtered front's candidate test ("front" method): a triangle of the triangulation is a
/// candidate when its edges are at most max_edge_m (metres) and its corners' unit normals agree
/// pairwise within max_normal_angle_deg and with the triangle's plane within
/// max_facet_angle_deg; candidates are taken in CGAL's priority order (the radius of the
/// smallest Delaunay sphere through the triangle).
struct FrontFilter {
    double max_edge_m = 0.0;
    double max_normal_angle_deg = 0.0;
    double max_facet_angle_deg = 0.0;
};

/// The advancing front through the points `xyz` with unit `normals` (world frame, metres) into
/// `mesh` (replaced): every candidate triangle CGAL's front selects, oriented along its corners'
/// mean normal, made a consistently oriented manifold mesh (non-manifold vertices duplicated;
/// a closed mesh faces outward). `filter` null = CGAL's default priority (every triangle a
/// candidate). radius_ratio_bound and beta (radians) are CGAL's `run` parameters.
void advancing_front(const std::vector<Eigen::Vector3d>& xyz,
                     const std::vector<Eigen::Vector3d>& normals, const FrontFilter* filter,
                     double radius_ratio_bound, double beta, Mesh& mesh);

}  // namespace rgbd::reconstruction::internal
