// Self-intersections of a triangle mesh: found (CGAL Polygon_mesh_processing::self_intersections,
// box intersection of the faces' bounding boxes, then exact triangle-triangle tests) and
// repaired (PMP::experimental::remove_self_intersections, CGAL 5.5, without its smoothing: the
// faces around each intersecting region are removed and the hole is refilled; the regions still
// crossing are then smoothed in place (PMP::angle_and_area_smoothing) and refilled again, in
// passes kept only when they leave fewer crossings; docs/algorithms.md §14; the Delaunay
// triangulation that its hole filling searches orders its cells by creation, not by address, so the
// same mesh is repaired the same way in every process). A closed mesh that crosses itself bounds no
// volume: slicers and boolean operations (corefinement) reject it, and Open3D's is_watertight is
// false. The advancing front and the closure's hole patches (a faired patch over a non-planar hole,
// a flat base over a rim whose projection folds) both make a few (docs/algorithms.md §14). Heavy
// CGAL templates live in self_intersections.cpp only.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include "toolkit/mesh.hpp"
#include "toolkit/report.hpp"

namespace rgbd::reconstruction {

/// The pairs of faces of `mesh` that intersect other than at a shared edge or vertex (in a
/// deterministic order: by the first face's index, then the second's; first < second).
/// Degenerate (zero-area) faces count as intersecting their neighbours, as in CGAL.
std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> self_intersecting_pairs(
    const Mesh& mesh);

/// Counts of self_intersecting_pairs(): self_intersecting_pairs (face pairs) and
/// self_intersecting_faces (faces in at least one pair); 0 and 0 for a mesh that bounds a
/// volume without crossing itself.
Report self_intersection_counts(const Mesh& mesh);

/// Removes the self-intersections of `mesh` (faces are removed around each intersecting region
/// and the hole refilled, CGAL's repair; then up to 3 passes in which the faces still crossing
/// and two rings round them are smoothed in place and refilled again, a pass kept only if it
/// leaves fewer pairs), keeping the mesh closed when it was closed: a hole the repair leaves is
/// closed again by CGAL's hole filling (triangulated, refined, faired). Vertex properties of new
/// vertices take their maps' defaults. Report: pairs_before, faces_involved, faces_before,
/// faces_after, pairs_after (counted again after the repair: 0 unless it failed, then the mesh
/// keeps what could not be undone), holes_refilled, smoothing_passes (kept), faces_smoothed,
/// time_s.
Report repair_self_intersections(Mesh& mesh);

/// Repairs the closure patches that fold onto themselves (docs/algorithms.md §14): `patch` lists
/// the faces the closure added; its connected components (sharing edges) are the patches. Faces
/// of one patch that cross each other (a faired patch over a strongly non-planar hole folds:
/// the cow's belly between its legs, the jug's mouth, the walls of a base cut round two feet)
/// are removed with their surroundings and the hole refilled (CGAL's repair, then the smoothing
/// passes, as repair_self_intersections; a pass is kept only if it leaves fewer folded pairs and
/// no more crossing pairs in the whole mesh). Crossings between two patches, or between a patch and
/// the reconstructed surface, are left: they mark a wrong topology (two disks where the unseen band
/// round a neck needs a tube), which a local repair replaces by a flat band that invents more
/// than it removes. `patch` is updated to the faces added or refilled after the repair (the
/// mesh's garbage is collected). Report: patch_pairs (crossing pairs among the patch faces),
/// folded_pairs (within one patch), faces_involved, regions and largest_region_faces (the
/// involved faces' connected components across edges: CGAL repairs each as one region; its cost
/// grows with the region), holes_refilled, smoothing_passes (kept), faces_smoothed,
/// pairs_after_each_refill (folded pairs after the first refill and after each pass tried; the
/// last is a pass put back when it is not below the one before), pairs_after (folded pairs
/// left), time_s.
Report repair_folded_patches(Mesh& mesh, std::vector<Mesh::Face_index>& patch);

}  // namespace rgbd::reconstruction
