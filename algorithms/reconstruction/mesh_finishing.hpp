// Finishing steps of a reconstructed mesh (docs/algorithms.md §14): dropping small components,
// closing every boundary loop (CGAL Polygon_mesh_processing hole filling: Liepa 2003,
// "Filling holes in meshes"; triangulate, refine, fair), and edge-collapse simplification to a
// face budget (CGAL Surface_mesh_simplification with Garland-Heckbert quadrics, "Surface
// simplification using quadric error metrics", 1997). Internal to algorithms/reconstruction;
// heavy CGAL templates live in mesh_finishing.cpp only.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <optional>
#include <vector>

#include "toolkit/mesh.hpp"
#include "toolkit/report.hpp"

namespace rgbd::reconstruction::internal {

/// Whether a sensor saw point p (world frame) with outward unit normal n as empty space.
using SeenEmpty = std::function<bool(const Eigen::Vector3d& p, const Eigen::Vector3d& n)>;

/// Removes connected components with fewer faces than `min_fraction` of the largest one's (and
/// isolated vertices); returns the number of components removed.
std::size_t drop_small_components(Mesh& mesh, double min_fraction);

/// Closes every boundary loop. A cut gets a flat refined patch; other loops are triangulated,
/// refined and faired (up to `fair_max_edges` edges; larger ones only refined); when CGAL finds
/// no triangulation, a fan around the loop's centroid, refined and faired. With `up` (world up),
/// the cut is where the object stood: the loops whose robust plane (refitted without the
/// vertices far off it: gaps of a ragged rim, grazing noise) is within 30 degrees of horizontal,
/// with an RMS residual under a tenth of the loop's radius and the centre in the lowest 15% of
/// the mesh's height, plus every other loop of 8+ edges within 30 degrees of horizontal whose
/// deep quintile reaches their rim's band (a rim split into several loops). All of them share one
/// cut plane (metres, world frame), the robust plane of their pooled vertices moved to its deep
/// quintile (the sensors rarely see the last millimetres above a base); the sides are extended
/// straight down to it and capped flat. Without `up`, a
/// cut is a planar loop meeting the surface at a crease (the faces along it steep to its plane).
/// With `ground` (n, d: n . p + d the height above the ground, metres) and the extraction's cut
/// `ground_margin_m`: when the cut's rim reaches down to the ground (its deep quintile within
/// the margin plus 3 robust RMS of the rim's plane, at least 1 cm, plus 3 of the rim's median
/// edge lengths, what the cleaning and meshing after the cut wear off its edge), the object
/// stood on the ground: the base keeps the cut's own plane and goes down until its lowest point
/// over the rim touches the ground (an oblique cut rests on one side, no wedge under it). Otherwise
/// the base is the rim's own plane at its deep quintile (never lower than the rim's lowest vertex:
/// no skirt below what the sensors saw). Once every loop is closed, each closed connected component
/// with a negative signed volume (inside out) is reversed (report: components_reversed). With
/// `seen_empty` (whether a sensor saw the point with that outward normal as empty space), every
/// faired or refined patch, and the flat base of a cut that does not rest on the ground (report:
/// flat_cuts_carvable), is carved back out of that space, for at most `carve_steps` steps (0 = not
/// carved; report: carved_patches, carved_vertices; the walls of a base that rests on the ground
/// are carved before it is capped, their feet moved inward on the base plane while the sensors saw
/// through them: closure_carving.hpp carve_walls, report carved_wall_feet): displaced inward along
/// its normals where it was seen empty, smoothly, no deeper than half a vertex's distance to the
/// rim; then the patches with more than `seen_through_max` of their face centres still seen empty
/// are counted (report: seen_through): surface the sensors contradict. They are kept. The result is
/// closed (CGAL::is_closed). Report: holes, faired, refined, flat_cuts, fans, faces_added,
/// largest_hole_edges, up (null when unknown), base ("ground" or "rim", with rim_above_ground_m,
/// reach_m and rim_tilt_deg, the cut's tilt to the ground, when a ground is known), time_s. `added`
/// (optional) receives the faces created.
Report close_holes(Mesh& mesh, const std::optional<Eigen::Vector3d>& up = std::nullopt,
                   std::size_t fair_max_edges = 300, std::vector<Mesh::Face_index>* added = nullptr,
                   const std::optional<Eigen::Vector4d>& ground = std::nullopt,
                   double ground_margin_m = 0.0, const SeenEmpty& seen_empty = {},
                   double seen_through_max = 0.5, int carve_steps = 40);

/// Removes the faces of folds and spikes, the defects an interpolating front leaves on noisy
/// points: both faces of every edge across which the face normals differ by more than
/// `max_fold_deg` degrees (a flap folded back onto its neighbour, a crumple), and border faces
/// that stick out (two border edges, or one border edge and a smallest angle under
/// `spike_angle_deg` degrees: the spikes along silhouettes and thin rims). `rounds` passes
/// (each sees the border the previous one left). Afterwards non-manifold vertices are split,
/// and components under `min_component_fraction` of the largest one's dropped. The holes left
/// are closed by close_holes() when the mesh must be watertight. Report: fold_faces,
/// spike_faces, components_dropped.
Report remove_folds_and_spikes(Mesh& mesh, double max_fold_deg = 120.0,
                               double spike_angle_deg = 10.0, int rounds = 3,
                               double min_component_fraction = 0.01);

/// Runs `edit` on `mesh` (it may add, remove and recycle faces and collect the garbage), then
/// sets `faces` to those of its faces that survive plus every face `edit` created: a face
/// property tracks them through the edit (new faces take its default). The mesh's garbage is
/// collected.
void track_faces(Mesh& mesh, std::vector<Mesh::Face_index>& faces,
                 const std::function<void()>& edit);

/// Regularises the triangles: isotropic remeshing (CGAL PMP::isotropic_remeshing, Botsch and
/// Kobbelt 2004: 3 iterations of splits, collapses and flips; no tangential relaxation) of the
/// faces of `patch` plus their one-ring, to the median edge length of the other faces; then,
/// over the whole mesh, needles (longest / shortest edge > 4, shortest edge under that median)
/// are collapsed and caps (an angle over 160 degrees) flipped
/// (PMP::experimental::remove_almost_degenerate_faces). Borders stay borders; a closed mesh
/// stays closed. `patch` is updated (track_faces): its surviving faces and every face the
/// remeshing made (in the one-ring too). Report: remeshed_faces, target_edge_m,
/// degenerate_removed, time_s.
Report regularize_faces(Mesh& mesh, std::vector<Mesh::Face_index>& patch);

/// Edge collapse (Garland-Heckbert plane quadrics, bounded normal change) until the mesh has
/// at most `target_faces` faces (or no collapse is possible). Borders stay borders and a
/// closed mesh stays closed. Report: faces_before, faces_after, collapsed_edges, time_s.
Report simplify_to_faces(Mesh& mesh, std::size_t target_faces);

}  // namespace rgbd::reconstruction::internal
