// The neighbour lists behind hole detection's neighbourhood graphs (algorithms/holes/
// neighbourhood.cpp), for hole_detection.cpp, which builds the gradient's and the criteria's
// graphs from one pass. Internal: not a public header.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "algorithms/holes/hole_detection.hpp"
#include "algorithms/internal/kd_tree.hpp"

namespace rgbd::holes::detail {

/// Directed neighbour lists N(p) = kNN(k) union radius(radius_factor * spacing), sorted by
/// (squared distance, index), capped, in compressed rows; before symmetrisation.
struct Directed {
    std::vector<std::uint32_t> offset;  ///< n + 1
    std::vector<std::uint32_t> index;
};

/// The directed lists of several option sets over one tree, in one pass: one kNN query with
/// the largest k and, when the sets share the radius, one radius query per point. A set with a
/// smaller k takes the first k + 1 results of the larger query: the same set as its own query
/// unless the (k+1)-th and (k+2)-th distances tie, and then its own query is run. Rows are
/// built in chunks of fixed size (no n x cap array), in parallel; the result does not depend
/// on the thread count. `spacing_m`: the point spacing the radii are multiples of, metres.
std::vector<Directed> directed_lists(const std::vector<Eigen::Vector3d>& points,
                                     const rgbd::internal::KdTree& tree, double spacing_m,
                                     const std::vector<NeighbourhoodOptions>& sets);

/// The neighbourhood graph of directed lists: as they are, or made symmetric (rows sorted,
/// duplicates removed).
Neighbourhood graph_from(const Directed& directed, bool symmetric);

}  // namespace rgbd::holes::detail
