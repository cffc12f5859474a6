// Polygon soup shared by the mesh readers of io/ (PLY, OFF, OBJ): vertices with optional
// colours and normals plus polygons, turned into a Surface_mesh or a PointCloud.
// See also: io/mesh_io.hpp, io/ply_stream.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::io::internal {

struct MeshSoup {
    std::vector<Point_3> points;
    std::vector<MeshColor> colors;  ///< empty or one per point
    std::vector<Vector_3> normals;  ///< empty or one per point
    /// Polygon k uses face_vertices[face_offsets[k] .. face_offsets[k + 1]); indices are
    /// checked by the parser (all < points.size()).
    std::vector<std::size_t> face_offsets{0};
    std::vector<std::uint32_t> face_vertices;

    std::size_t face_count() const { return face_offsets.size() - 1; }
    void add_face(const std::vector<std::uint32_t>& polygon) {
        face_vertices.insert(face_vertices.end(), polygon.begin(), polygon.end());
        face_offsets.push_back(face_vertices.size());
    }
};

/// Builds `mesh` (cleared first) from the soup: polygons become triangle fans, triangles
/// with a repeated vertex are dropped, and a triangle the halfedge structure rejects
/// (non-manifold edge or vertex, inconsistent orientation) gets its own copies of its
/// vertices so that no face is lost. Colours go to "v:color", normals to "v:normal".
/// Returns the number of triangles that needed vertex copies.
std::size_t build_mesh(const MeshSoup& soup, Mesh& mesh);

/// The soup's vertices (with colours and normals) as a point cloud.
void soup_to_cloud(const MeshSoup& soup, PointCloud& cloud);

}  // namespace rgbd::io::internal
