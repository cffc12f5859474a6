// Kernel and basic geometric types shared by every library of the toolkit.
#pragma once

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <Eigen/Core>

namespace rgbd {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point_3 = Kernel::Point_3;
using Vector_3 = Kernel::Vector_3;

inline Eigen::Vector3d to_eigen(const Point_3& p) { return {p.x(), p.y(), p.z()}; }
inline Eigen::Vector3d to_eigen(const Vector_3& v) { return {v.x(), v.y(), v.z()}; }
inline Point_3 to_point(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }
inline Vector_3 to_vector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace rgbd
