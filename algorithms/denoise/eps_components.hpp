// Exact components of the eps graph over a point set on a cell grid (docs/algorithms.md,
// density-based cleaning: the cluster pass). Internal to algorithms/denoise (not installed).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace rgbd::denoise::detail {

/// Components of the eps graph over `pts` (p ~ q iff |p - q| <= eps), exactly, without a
/// radius search per point: points are binned in cells of side c = eps / sqrt(3) (any two
/// points of a cell are closer than eps, so a cell lies in one component) and only cells at
/// most 2 apart on every axis can hold a linked pair (3 cells apart means more than 2c > eps
/// on that axis); a pair of cells is tested point by point, stopping at the first link, and
/// skipped when both already share a component. Writes each point's component
/// label (a cell index, equal for the points of one component) to `label`. Returns false
/// without touching `label` when the grid would not fit 21 bits per axis.
bool eps_components(const std::vector<Eigen::Vector3d>& pts, double eps,
                    std::vector<std::uint32_t>& label);

}  // namespace rgbd::denoise::detail
