// CGAL's Poisson surface reconstruction (Kazhdan et al. 2006, as implemented by CGAL's
// Poisson_surface_reconstruction_3 on a Delaunay refinement; docs/algorithms.md §8), kept in a
// translation unit of its own. Internal to algorithms/: public headers never expose it.
#pragma once

#include <utility>
#include <vector>

#include "toolkit/mesh.hpp"

namespace rgbd::internal {

/// Solves the Poisson equation for the oriented points `pwn` (point, unit normal; metres) and
/// meshes its zero level set into `mesh` with CGAL's surface mesher: `spacing` is the points'
/// average spacing (metres), `angle_deg` the smallest facet angle, `radius` and `distance` the
/// facets' largest radius and distance to the surface in multiples of `spacing`. Returns false
/// when the solver fails. The mesher draws points from CGAL's default random generator: seed it
/// for repeatable meshes.
bool poisson_surface(const std::vector<std::pair<Point_3, Vector_3>>& pwn, double spacing,
                     double angle_deg, double radius, double distance, Mesh& mesh);

}  // namespace rgbd::internal
