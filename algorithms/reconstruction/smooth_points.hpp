// Normal-aware moving-least-squares projection of an oriented point cloud, the denoising step
// before an interpolating mesher (docs/algorithms.md §14, "front" method). Each point is projected
// on a quadratic height field fitted, in the frame of its weighted PCA plane, to the neighbours
// within a radius whose normals agree with its own: the two sides of a thin part (a fin, a
// finger, a sleeve) never average into each other. Sources: Levin 1998 / Alexa et al. 2001
// (MLS surfaces); Cazals and Pouget 2003 (jet fitting, CGAL jet_smooth_point_set); the normal
// test is ours [M]. Internal to algorithms/reconstruction.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace rgbd::reconstruction::internal {

struct SmoothOptions {
    /// Neighbourhood radius (metres, > 0).
    double radius = 0.0;
    /// Neighbours whose normal makes more than this angle with the point's own are ignored.
    double max_normal_angle_deg = 60.0;
    /// Fewer agreeing neighbours than this: the point is kept as it is.
    int min_neighbors = 6;
    /// A quadric is fitted from this many agreeing neighbours on (a plane below).
    int quadric_neighbors = 15;
    /// Projection rounds (each re-reads the previous round's points).
    int iterations = 1;
};

/// Projects `points` in place and replaces `normals` (unit, same side as before) by the
/// normals of the fitted surfaces. TBB-parallel, identical for any thread count.
/// Returns how many points moved (had enough agreeing neighbours).
std::size_t smooth_points(std::vector<Eigen::Vector3d>& points,
                          std::vector<Eigen::Vector3d>& normals, const SmoothOptions& options);

}  // namespace rgbd::reconstruction::internal
