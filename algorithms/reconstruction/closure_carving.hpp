// Closure patches carved out of the space the sensors saw empty (docs/method.md stage 8,
// docs/algorithms.md; [M], ours): the watertight closure's faired patches may bulge through
// space the sensors saw through; close_holes() (mesh_finishing.hpp) orients the closed mesh
// outward and carves each patch back to the boundary of that space.
#pragma once

#include <cstddef>
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

}  // namespace rgbd::reconstruction::internal
