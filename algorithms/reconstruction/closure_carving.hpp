// Closure patches carved out of the space the sensors saw empty (docs/method.md stage 8,
// docs/algorithms.md; [M], ours): the watertight closure's faired patches may bulge through
// space the sensors saw through; close_holes() (mesh_finishing.hpp) orients the closed mesh
// outward and carves each patch back to the boundary of that space.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <utility>
#include <vector>

#include "algorithms/reconstruction/mesh_finishing.hpp"

namespace rgbd::reconstruction::internal {

/// Reverses the faces of every closed connected component whose signed volume is negative
/// (inside out: its normals point inward), so that every closed component bounds its volume
/// with outward normals; open components are left as they are. Returns the number reversed.
std::size_t orient_outward(Mesh& mesh);

/// Space carving of one closure patch (`faces`, its new interior `vertices`; the mesh closed
/// and oriented outward): the patch is displaced inward, each vertex along its normal on the
/// faired patch by a depth s >= 0 that is smooth over the patch and 0 on its rim. Each step
/// deepens s by half the patch's mean edge length at the vertices a sensor saw as empty space
/// (`seen_empty` at the vertex and its normal), then smooths s once (each vertex to the mean of
/// itself and its neighbours' mean, the rim counting 0), until no sensor sees a vertex of the
/// patch empty or after `max_steps` steps. No vertex goes deeper than half its distance to the
/// rim (a dent of at most 27 degrees from the rim), so that noisy evidence cannot push a patch
/// through the object it closes (without that bound the seated cellist's seat patch went 22 cm
/// deep and its invented area rose from 14.7% to 23.5%). A faired patch spans its rim smoothly,
/// so over a wide hole the sensors did not see into (an animal's belly between its legs, under
/// a seat) it bulges out through space the side sensors saw through; carving brings it back to
/// the boundary of that space, the visual hull (Laurentini, "The visual hull concept for
/// silhouette-based image understanding", PAMI 1994; space carving: Kutulakos and Seitz, IJCV
/// 2000), while the patch stays closed and smooth (the directions are fixed: moving each vertex
/// along its own current normal roughened the patch until normals flipped). Returns the number
/// of vertices seen empty at least once.
std::size_t carve_patch(Mesh& mesh, const std::vector<Mesh::Face_index>& faces,
                        const std::vector<Mesh::Vertex_index>& vertices,
                        const SeenEmpty& seen_empty, int max_steps);

/// Space carving of the walls of a base that rests on the ground (close_holes, before the base
/// is capped): each wall runs from a rim vertex (`walls[i].first`, measured, fixed) down to its
/// foot on the base plane (`walls[i].second`; the walls in loop order, the plane through `point`
/// with downward unit normal `down`). A straight wall is a skirt round a bottom that curves inward
/// below the last rim the sensors kept (a seated bear, a bevelled plinth): the sensors saw the
/// floor through it. Each step moves the feet the wall was seen empty at (`seen_empty` at a third
/// and two thirds of the way down, with the wall's outward normal) inward in the base plane by
/// half the rim's mean edge length, along the rim's outward direction there (the chord between
/// the loop's vertices w = n/16, 2 to 8, before and after it, turned a right angle: a ragged
/// rim's own edges point every way), then smooths the feet's displacements once along the loop;
/// until no wall is seen empty or after `max_steps` steps. No foot goes further in than 0.4 of the
/// way across the base (along its inward direction to the loop's far side), nor than 0.7 of the
/// radius of a convex bend (where feet moved inward converge), so that the base keeps its extent
/// where the evidence is noisy. The base is capped as a polygon: feet moved inward round a convex
/// bend converge and cross, leaving a small loop (a swallowtail, as on any inward offset curve);
/// the feet of its shorter side (at most a quarter of the loop) are put on the chord that cuts it
/// off, round after round, until the feet cross no more often than the rim's own ragged loop does
/// (the bear in a room: 36-60 crossings, its rim 4-11, none after). Should that fail in 8 rounds,
/// the displacements round the crossing edges are halved instead (all dropped after 8 more).
/// Returns the number of feet moved.
std::size_t carve_walls(Mesh& mesh,
                        const std::vector<std::pair<Mesh::Vertex_index, Mesh::Vertex_index>>& walls,
                        const Eigen::Vector3d& point, const Eigen::Vector3d& down,
                        const SeenEmpty& seen_empty, int max_steps);

}  // namespace rgbd::reconstruction::internal
