// Surface reconstruction of an oriented point cloud into a coloured triangle mesh
// (docs/algorithms.md §14). Methods:
// - "front" (default) [M]: normal-aware MLS projection of the points (smooth_points.hpp: the two
//   sides of thin parts never mix), thinning to a grid of about the point spacing, then CGAL
//   advancing front (Cohen-Steiner and Da 2004) restricted to triangles whose edges are short
//   and whose corners' normals agree: it interpolates the denoised samples, keeps thin parts
//   and detail, and invents no surface where no sensor looked (holes stay open unless
//   `watertight`).
// - "advancing-front": CGAL advancing front on the raw points (interpolates the noise).
// - "poisson": CGAL Poisson (Kazhdan, Bolitho and Hoppe 2006, unscreened, solved on a refined
//   Delaunay triangulation, CGAL poisson_surface_reconstruction_delaunay); closed.
// Then: small components dropped, (front, advancing-front) folds and spikes removed,
// `watertight` closes every boundary loop (CGAL hole filling, mesh_finishing.hpp), the hole
// patches are remeshed isotropically and needles / caps removed, `target_faces` simplifies by edge
// collapse, and vertex colours come by inverse-distance weighting of the nearest coloured input
// points, measured points preferred over synthetic ones. See also:
// algorithms/normals/estimate_normals.hpp (orient normals first),
// algorithms/sampling/voxel_downsample.hpp, CGAL examples poisson_reconstruction.cpp and
// reconstruction_surface_mesh.cpp.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>

#include "algorithms/holes/hole_detection.hpp"
#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"
#include "toolkit/progress.hpp"
#include "toolkit/report.hpp"

namespace rgbd::reconstruction {

struct ReconstructionOptions {
    /// "front" (denoised interpolation, the default), "advancing-front" (raw interpolation) or
    /// "poisson" (closed, approximating).
    std::string method = "front";
    /// Close every boundary loop of the result (hole filling), so the mesh is a closed
    /// 2-manifold.
    bool watertight = false;
    /// World up (any length), e.g. sensors_up() of the views' poses. With it, `watertight` knows
    /// the object's support: a flat loop at the bottom of the object, facing down, is the cut
    /// where the object stood (base of a bust, floor under the feet) and gets a flat cap; every
    /// other loop (crown, under the chin) continues the surface smoothly. Without it, a loop is
    /// taken for a cut by its shape alone (planar, meeting the surface at a crease).
    std::optional<Eigen::Vector3d> up;
    /// The ground the object stood on (world frame: unit normal n pointing up and offset d,
    /// n . p + d the height above it, metres), e.g. segment::world_ground of the views, and the
    /// margin the extraction cut above it. With it, `watertight` puts the flat base of a cut
    /// that reaches down to the ground (within the margin and the rim's noise) on the ground;
    /// a cut that ends above it is capped at its own rim, never below.
    std::optional<Eigen::Vector4d> ground;
    double ground_margin_m = 0.0;
    /// The sensors of the measured points (world poses, intrinsics). With them, `watertight`
    /// checks every faired hole patch against the space the sensors saw empty
    /// (holes::FreeSpace over the measured input points: a sensor that faced the patch and
    /// measured a surface well behind it, or background inside the object's silhouette, saw
    /// through it) and reports the patches with more than `seen_through_max` of their faces
    /// seen through (holes.seen_through): an opening the sensors looked into, such as the back
    /// of a mask. They stay closed (removing them opened simple closed objects).
    std::vector<holes::SensorView> sensors;
    /// More measurements of the same sensors (world frame, metres) that are not the subject's:
    /// what the object extraction and the cleaning removed around it (the floor beside its base,
    /// pipeline/source_evidence.hpp). They go into the free-space maps with the measured input
    /// points, never into the surface: a ray that met the floor beyond a patch passed through it.
    std::vector<Eigen::Vector3d> evidence_points;
    double seen_through_max = 0.5;
    /// `watertight` with `sensors`: every faired closure patch, and the walls of a base on the
    /// ground (their feet moved inward on the base: a skirt round a rounded bottom), is first
    /// carved out of the space at least `carve_votes` sensors saw empty (mesh_finishing.hpp:
    /// close_holes), for at most `carve_steps` steps of half its edge length (0 = no carving).
    /// The background test uses a
    /// window of 3 pixels around the ray (holes::FreeSpaceOptions::background_window), one more
    /// than the fill's: the sensors lose the object's grazing rim, so the measured silhouette
    /// is a little smaller than the object's. On the bull of the variety set (seed 1), one
    /// sensor and a 2-pixel window carved through the belly (invented area inside the truth
    /// 0.17% -> 5.1%); two sensors and 3 pixels: 0.20%, invented 4.4% -> 3.4%.
    int carve_steps = 40;
    int carve_votes = 2;
    /// `watertight`: holes with at most this many boundary edges are triangulated, refined and
    /// faired (CGAL PMP, Liepa 2003); larger ones only triangulated and refined. At 300 (before)
    /// the one hole of 314-658 edges under Homer's feet, the cow's, the bull's and the cellist's
    /// seat was refined flat and invented 0.6-1.4% more area than faired (variety set, seed 1:
    /// Homer 5.0 -> 3.6%, cow 4.2 -> 3.5%, bull 5.6 -> 5.0%, cellist 15.5 -> 14.9%; six other
    /// objects identical), at 0.05-0.3 s for all holes.
    std::size_t fair_max_edges = 1000;
    /// Simplify by edge collapse to at most this many faces; 0 = keep the reconstruction's.
    std::size_t target_faces = 0;
    /// Connected components with fewer faces than this share of the largest one's are dropped
    /// (noise islands); 0 keeps everything.
    double min_component_fraction = 0.01;
    /// front: MLS radius in multiples of ŝ.
    double smooth_radius = 3.0;
    /// front: MLS rounds.
    int smooth_iterations = 1;
    /// front: thinning voxel in multiples of ŝ (0 = no thinning).
    double front_voxel = 1.0;
    /// front: longest triangle edge in multiples of ŝ (gaps wider than this stay open).
    double front_max_edge = 6.0;
    /// front: corners whose normals differ by more than this never share a triangle, degrees
    /// (opposite sides of a thin part differ by about 180, the faces of a square edge by 90).
    double front_max_normal_angle_deg = 120.0;
    /// front: triangles tilted more than this from their corners' mean normal are never taken
    /// (they would stand across the surface), degrees.
    double front_max_facet_angle_deg = 75.0;
    /// front and advancing-front: remove folds and spikes before `watertight` closes the holes,
    /// then regularise the triangles (mesh_finishing.hpp: remove_folds_and_spikes,
    /// regularize_faces): no flaps, no spikes along silhouettes, no slivers; with `watertight`,
    /// the closure's patches that fold onto themselves are repaired first
    /// (self_intersections.hpp: repair_folded_patches).
    bool clean = true;
    /// Last, after any simplification: the faces that cross others are removed and their holes
    /// refilled (self_intersections.hpp), so that a closed mesh bounds a volume (slicers,
    /// booleans). Off by default: where two closure patches span one unseen band (a groove
    /// round a neck) the repair replaces them by a band that invents more surface than it
    /// removes (docs/algorithms.md §14).
    bool repair_self_intersections = false;
    /// clean: faces whose normals differ by more than this across an edge are a fold, degrees.
    double fold_angle_deg = 120.0;
    /// clean: a border face with a smaller angle than this is a spike, degrees.
    double spike_angle_deg = 10.0;
    /// The input is voxel-downsampled (voxel grown from ŝ) until it has at most this many points,
    /// to bound time and memory; 0 = use every point.
    std::size_t max_points = 60000;
    /// Poisson surface mesher: minimum triangle angle, degrees (CGAL example: 20).
    double sm_angle_deg = 20.0;
    /// Poisson: maximum radius of the surface Delaunay balls, in average spacings (CGAL: 30).
    double sm_radius = 30.0;
    /// Poisson: maximum distance mesh - implicit surface, in average spacings (CGAL: 0.375).
    double sm_distance = 0.375;
    /// Advancing front: radius-ratio bound of candidate triangles (CGAL default 5).
    double af_radius_ratio_bound = 5.0;
    /// Advancing front: maximal dihedral angle deviation, radians (CGAL default 0.52).
    double af_beta = 0.52;
    /// Nearest coloured input points blended per vertex (IDW).
    int color_k = 8;
    /// Only observed points (neither `synthetic` nor `uncoloured`: measured, and seen by the
    /// colour camera) colour a vertex when one lies within this multiple of ŝ (docs/algorithms.md
    /// §14: 2 ŝ).
    double color_original_radius = 2.0;
    /// The caller's work that does not depend on the surface (a report picture of the input,
    /// say): run once in a task beside the surface's sequential step (the advancing front,
    /// Poisson's solve), where a second thread would otherwise idle, and waited for before
    /// reconstruct_surface() returns (its exceptions come out of it). Empty: none.
    std::function<void()> beside_surface;
    /// Throws InputError on absurd values or an unknown method.
    void check() const;
};

/// Reconstructs a triangle mesh from a cloud with oriented normals.
/// Output: a valid CGAL Surface_mesh without isolated vertices, garbage collected; with a
/// "v:color" map when the cloud has colours. Poisson output, and any output with `watertight`,
/// is closed.
/// Throws InputError when the cloud has fewer than 100 points, has no normals ("estimate
/// them first"), or has non-finite values; AlgorithmError when CGAL fails (e.g. Poisson solver)
/// or `progress` cancels. Report (if given): method, points_in, points_used, voxel_m,
/// average_spacing_m, used_spacing_m (ŝ after the down-sampling, which scales the front),
/// smoothing / holes / simplification sub-reports, components_dropped,
/// vertices, faces, border_edges, closed, colored, mesh_time_s, color_time_s, time_s.
Mesh reconstruct_surface(const PointCloud& cloud_with_oriented_normals,
                         const ReconstructionOptions& options, Report* report = nullptr,
                         const Progress& progress = {});

}  // namespace rgbd::reconstruction
