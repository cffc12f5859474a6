// A translation unit of its own for CGAL's Poisson solver: sanitizer builds exempt it from one
// check (algorithms/reconstruction/CMakeLists.txt says which and why).
#include "algorithms/internal/poisson_solver.hpp"

#include <CGAL/poisson_surface_reconstruction.h>
#include <CGAL/property_map.h>

namespace rgbd::internal {

bool poisson_surface(const std::vector<std::pair<Point_3, Vector_3>>& pwn, double spacing,
                     double angle_deg, double radius, double distance, Mesh& mesh) {
    using Pwn = std::pair<Point_3, Vector_3>;
    return CGAL::poisson_surface_reconstruction_delaunay(
        pwn.begin(), pwn.end(), CGAL::First_of_pair_property_map<Pwn>(),
        CGAL::Second_of_pair_property_map<Pwn>(), mesh, spacing, angle_deg, radius, distance);
}

}  // namespace rgbd::internal
