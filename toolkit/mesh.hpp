// Mesh: a CGAL Surface_mesh with optional per-vertex colour ("v:color") and normal
// ("v:normal") properties (docs/architecture.md, the data model).
#pragma once

#include <CGAL/IO/Color.h>
#include <CGAL/Surface_mesh.h>

#include <optional>

#include "toolkit/types.hpp"

namespace rgbd {

using Mesh = CGAL::Surface_mesh<Point_3>;
using MeshColor = CGAL::IO::Color;
using VertexColorMap = Mesh::Property_map<Mesh::Vertex_index, MeshColor>;
using VertexNormalMap = Mesh::Property_map<Mesh::Vertex_index, Vector_3>;

inline constexpr const char* kVertexColor = "v:color";
inline constexpr const char* kVertexNormal = "v:normal";

/// The vertex colour map if the mesh has one.
inline std::optional<VertexColorMap> vertex_colors(const Mesh& mesh) {
    auto [map, found] = mesh.property_map<Mesh::Vertex_index, MeshColor>(kVertexColor);
    if (!found) return std::nullopt;
    return map;
}

/// Adds (or returns) the vertex colour map, default grey.
inline VertexColorMap add_vertex_colors(Mesh& mesh) {
    return mesh
        .add_property_map<Mesh::Vertex_index, MeshColor>(kVertexColor, MeshColor(128, 128, 128))
        .first;
}

}  // namespace rgbd
