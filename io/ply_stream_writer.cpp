// Writing stream documents (binary little-endian PLY). See io/ply_stream.hpp.
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <istream>
#include <limits>
#include <optional>
#include <ostream>
#include <sstream>
#include <string_view>

#include "io/internal/mesh_soup.hpp"
#include "io/internal/ply_format.hpp"
#include "io/ply_stream.hpp"
#include "toolkit/error.hpp"
namespace rgbd::io {

namespace {

using namespace internal::ply;

void write_header(std::ostream& out, const std::vector<std::string>& comments,
                  const std::string& elements) {
    std::string h = "ply\nformat binary_little_endian 1.0\n";
    for (const std::string& c : comments) h += "comment " + one_line(c) + "\n";
    h += elements;
    h += "end_header\n";
    out.write(h.data(), static_cast<std::streamsize>(h.size()));
}

/// One output column of the vertex element.
struct Column {
    std::string name;
    PlyType type;
    std::function<void(PointSet::Index, unsigned char*)> put;
};

template <typename T>
bool try_column(const PointSet& points, const std::string& name, PlyType type,
                std::vector<Column>& out) {
    // Not a structured binding: clang 14 (the fuzz build) cannot capture one in a lambda.
    const auto lookup = points.property_map<T>(name);
    if (!lookup.second) return false;
    const auto map = lookup.first;
    out.push_back({name, type, [map](PointSet::Index i, unsigned char* p) {
                       const T v = map[i];
                       std::memcpy(p, &v, sizeof(T));
                   }});
    return true;
}

void check_finite(const Point_3& p, std::size_t i, const char* what) {
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z()))
        throw InputError(std::string(what) + ": point " + std::to_string(i) +
                         " has a non-finite coordinate");
}

void put_double(unsigned char*& p, double v) {
    std::memcpy(p, &v, 8);
    p += 8;
}

}  // namespace

void write_points(std::ostream& out, const PointCloud& cloud) {
    const PointSet& points = cloud.points;
    std::vector<Column> columns;
    for (const std::string& name : cloud.property_names()) {
        try_column<std::int8_t>(points, name, PlyType::kInt8, columns) ||
            try_column<std::uint8_t>(points, name, PlyType::kUint8, columns) ||
            try_column<std::int16_t>(points, name, PlyType::kInt16, columns) ||
            try_column<std::uint16_t>(points, name, PlyType::kUint16, columns) ||
            try_column<std::int32_t>(points, name, PlyType::kInt32, columns) ||
            try_column<std::uint32_t>(points, name, PlyType::kUint32, columns) ||
            try_column<float>(points, name, PlyType::kFloat32, columns) ||
            try_column<double>(points, name, PlyType::kFloat64, columns);
        // Properties of other C++ types have no PLY form and are not written.
    }
    const bool normals = points.has_normal_map();
    std::size_t stride = normals ? 48 : 24;
    std::string elements = "element vertex " + std::to_string(points.size()) + "\n";
    elements += "property double x\nproperty double y\nproperty double z\n";
    if (normals) elements += "property double nx\nproperty double ny\nproperty double nz\n";
    for (const Column& c : columns) {
        elements += std::string("property ") + type_name(c.type) + " " + c.name + "\n";
        stride += type_size(c.type);
    }
    std::size_t i = 0;
    for (auto idx : points) check_finite(points.point(idx), i++, "write_points");

    write_header(out, view_to_comments(cloud.view, DocumentKind::kPoints), elements);
    std::vector<unsigned char> buffer(points.size() * stride);
    unsigned char* p = buffer.data();
    for (auto idx : points) {
        const Point_3& q = points.point(idx);
        put_double(p, q.x());
        put_double(p, q.y());
        put_double(p, q.z());
        if (normals) {
            const Vector_3& n = points.normal(idx);
            put_double(p, n.x());
            put_double(p, n.y());
            put_double(p, n.z());
        }
        for (const Column& c : columns) {
            c.put(idx, p);
            p += type_size(c.type);
        }
    }
    out.write(reinterpret_cast<const char*>(buffer.data()),
              static_cast<std::streamsize>(buffer.size()));
    if (!out) throw IoError("write_points: output stream failed");
}

void write_mesh(std::ostream& out, const Mesh& mesh, const ViewInfo& view) {
    using V = Mesh::Vertex_index;
    const auto colors = vertex_colors(mesh);
    const auto [normals, has_normals] = mesh.property_map<V, Vector_3>(kVertexNormal);
    std::vector<std::uint32_t> index(mesh.num_vertices() + mesh.number_of_removed_vertices());
    std::size_t n = 0;
    for (V v : mesh.vertices()) {
        check_finite(mesh.point(v), n, "write_mesh");
        index[v.idx()] = static_cast<std::uint32_t>(n++);
    }
    std::string elements = "element vertex " + std::to_string(n) + "\n";
    elements += "property double x\nproperty double y\nproperty double z\n";
    if (has_normals) elements += "property double nx\nproperty double ny\nproperty double nz\n";
    if (colors) elements += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    elements += "element face " + std::to_string(mesh.number_of_faces()) + "\n";
    elements += "property list uchar int vertex_indices\n";
    std::vector<unsigned char> faces;
    for (auto f : mesh.faces()) {
        std::uint8_t count = 0;
        const std::size_t at = faces.size();
        faces.push_back(0);
        for (V v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
            const std::int32_t i = static_cast<std::int32_t>(index[v.idx()]);
            const auto* b = reinterpret_cast<const unsigned char*>(&i);
            faces.insert(faces.end(), b, b + 4);
            if (++count == 255) throw InputError("write_mesh: face with more than 254 vertices");
        }
        faces[at] = count;
    }
    write_header(out, view_to_comments(view, DocumentKind::kMesh), elements);

    const std::size_t stride = 24 + (has_normals ? 24 : 0) + (colors ? 3 : 0);
    std::vector<unsigned char> buffer(n * stride);
    unsigned char* p = buffer.data();
    for (V v : mesh.vertices()) {
        const Point_3& q = mesh.point(v);
        put_double(p, q.x());
        put_double(p, q.y());
        put_double(p, q.z());
        if (has_normals) {
            const Vector_3& nv = normals[v];
            put_double(p, nv.x());
            put_double(p, nv.y());
            put_double(p, nv.z());
        }
        if (colors) {
            const MeshColor c = (*colors)[v];
            *p++ = c.red();
            *p++ = c.green();
            *p++ = c.blue();
        }
    }
    out.write(reinterpret_cast<const char*>(buffer.data()),
              static_cast<std::streamsize>(buffer.size()));
    out.write(reinterpret_cast<const char*>(faces.data()),
              static_cast<std::streamsize>(faces.size()));
    if (!out) throw IoError("write_mesh: output stream failed");
}

void write_document(std::ostream& out, const Document& document) {
    if (document.kind == DocumentKind::kMesh) {
        write_mesh(out, document.mesh, document.cloud.view);
    } else {
        write_points(out, document.cloud);
    }
}

}  // namespace rgbd::io
