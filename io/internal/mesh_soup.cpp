#include "io/internal/mesh_soup.hpp"

#include <array>

namespace rgbd::io::internal {

std::size_t build_mesh(const MeshSoup& soup, Mesh& mesh) {
    mesh.clear();
    using V = Mesh::Vertex_index;
    const bool has_colors = !soup.colors.empty();
    const bool has_normals = !soup.normals.empty();
    std::optional<VertexColorMap> colors;
    std::optional<VertexNormalMap> normals;
    if (has_colors) colors = add_vertex_colors(mesh);
    if (has_normals)
        normals = mesh.add_property_map<V, Vector_3>(kVertexNormal, CGAL::NULL_VECTOR).first;
    mesh.reserve(static_cast<Mesh::size_type>(soup.points.size()),
                 static_cast<Mesh::size_type>(3 * soup.face_vertices.size()),
                 static_cast<Mesh::size_type>(soup.face_vertices.size()));
    std::vector<V> vertex(soup.points.size());
    auto copy_vertex = [&](std::size_t i) {
        const V v = mesh.add_vertex(soup.points[i]);
        if (colors) (*colors)[v] = soup.colors[i];
        if (normals) (*normals)[v] = soup.normals[i];
        return v;
    };
    for (std::size_t i = 0; i < soup.points.size(); ++i) vertex[i] = copy_vertex(i);

    std::size_t copied = 0;
    for (std::size_t f = 0; f < soup.face_count(); ++f) {
        const std::size_t begin = soup.face_offsets[f];
        const std::size_t end = soup.face_offsets[f + 1];
        for (std::size_t k = begin + 1; k + 1 < end; ++k) {
            const std::array<std::uint32_t, 3> t = {
                soup.face_vertices[begin], soup.face_vertices[k], soup.face_vertices[k + 1]};
            if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
            if (mesh.add_face(vertex[t[0]], vertex[t[1]], vertex[t[2]]) != Mesh::null_face())
                continue;
            mesh.add_face(copy_vertex(t[0]), copy_vertex(t[1]), copy_vertex(t[2]));
            ++copied;
        }
    }
    return copied;
}

void soup_to_cloud(const MeshSoup& soup, PointCloud& cloud) {
    cloud.points.clear();
    if (!soup.normals.empty()) cloud.points.add_normal_map();
    std::optional<PointCloud::ColorMaps> colors;
    if (!soup.colors.empty()) colors = cloud.add_colors();
    cloud.points.reserve(soup.points.size());
    for (std::size_t i = 0; i < soup.points.size(); ++i) {
        const auto idx = cloud.points.insert(soup.points[i]);
        if (!soup.normals.empty()) cloud.points.normal(*idx) = soup.normals[i];
        if (colors)
            colors->set(*idx,
                        {soup.colors[i].red(), soup.colors[i].green(), soup.colors[i].blue()});
    }
}

}  // namespace rgbd::io::internal
