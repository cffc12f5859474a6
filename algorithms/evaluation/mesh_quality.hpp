// Mesh cleanliness without ground truth: sliver triangles, folds (flaps and spikes), surface
// far from the measured points, and vertices left with the mesher's grey fill colour where
// points were observed.
//
// Definitions (all shares are in [0, 1]; "positive-area face" = a triangle with area > 0):
// - sliver: a face whose minimum interior angle is below the threshold (zero-area faces
//   count as slivers of angle 0). By count over all faces and by area over the total area.
// - fold edge: an edge with two positive-area faces whose unit normals differ by more than
//   fold_angle_deg (120 deg: the surface turns back on itself, a flap or the flank of a
//   spike). Share of the edges with two positive-area faces (boundary edges excluded).
// - spike vertex: a vertex with a positive-area face whose unit normal deviates from the
//   vertex's area-weighted normal (sum of the faces' area vectors) by more than
//   spike_angle_deg (60 deg, sharper than a cube corner's 54.7 deg), or whose area-weighted
//   normal vanishes (faces cancel out). Share of the vertices with a positive-area face.
// - far area: area-uniform samples of the mesh farther than far_tau_m from every input point
//   (nearest point, kd-tree), as a share of the samples = of the area.
// - grey vertex: a vertex whose colour equals the mesher's fill colour for vertices without
//   colour (128, 128, 128, reconstruction/mesh_colour.cpp and holes/large_holes.cpp)
//   within grey_tolerance per channel, while an input point lies within grey_tau_m: the
//   colour was lost although the surface was observed. Share of all vertices.
// - self-intersecting pairs: pairs of faces that cross other than at a shared edge or vertex
//   (CGAL PMP::self_intersections; reconstruction/self_intersections.hpp); a closed mesh with
//   any bounds no volume (slicers, booleans and Open3D's is_watertight reject it).
//
// See also: libigl `internal_angles`, Meshlab "Select Faces by angle / Compute quality
// (triangle aspect)", PMP::degenerate_faces (CGAL), VCGlib `tri::Clean::CountNonManifold*`.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "toolkit/mesh.hpp"
#include "toolkit/report.hpp"

namespace rgbd::evaluation {

/// Thresholds of mesh_quality().
struct MeshQualityOptions {
    /// Minimum-angle thresholds (degrees) of sliver faces: one key per threshold.
    std::vector<double> sliver_angles_deg{5.0, 10.0};
    /// Angle (degrees) between two adjacent faces' normals beyond which their edge is a fold.
    double fold_angle_deg = 120.0;
    /// Deviation (degrees) of a face normal from its vertex's area-weighted normal beyond
    /// which the vertex is a spike.
    double spike_angle_deg = 60.0;
    /// Mesh surface farther than this from every input point is "far" (metres).
    double far_tau_m = 0.003;
    /// A grey vertex counts only when an input point lies within this distance (metres).
    double grey_tau_m = 0.003;
    /// The fill colour of vertices the mesher could not colour, and the per-channel tolerance.
    std::uint8_t grey_level = 128;
    int grey_tolerance = 0;
    /// Area-uniform samples for the far area (with input points only).
    std::size_t samples = 100000;
    std::uint64_t seed = 1;
    /// Count the self-intersecting face pairs (about 0.2 s per 100,000 faces on 2 cores).
    bool self_intersections = true;

    /// Throws InputError for a non-finite or out-of-range threshold or samples == 0 or > 1e8.
    void check() const;
};

/// Cleanliness of a triangle mesh (definitions above).
///
/// @param mesh          triangle mesh (coordinates in metres).
/// @param input_points  the points the mesh was made from, in the mesh's frame, or null: then
///                      far_area_fraction_* and grey_vertex_fraction are not computed.
/// @return snake_case keys: faces, vertices, edges_interior, sliver_fraction_5deg,
///         sliver_area_fraction_5deg (one pair per threshold, fractional degrees with 'p'),
///         fold_edge_fraction, fold_edges, spike_vertex_fraction, spike_vertices; with input
///         points far_area_fraction_3mm (tau in mm) and grey_vertex_fraction (null when the
///         mesh has no vertex colours), grey_vertices; with options.self_intersections
///         self_intersecting_pairs and self_intersecting_faces; the thresholds; time_s.
/// @throws InputError for a mesh without faces, a non-triangle face, a non-finite vertex or
///         input point, or empty input points.
Report mesh_quality(const Mesh& mesh, const std::vector<Eigen::Vector3d>* input_points,
                    const MeshQualityOptions& options = {});

}  // namespace rgbd::evaluation
