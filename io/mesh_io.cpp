#include "io/mesh_io.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "io/internal/atomic_file.hpp"
#include "io/internal/file_text.hpp"
#include "io/internal/mesh_soup.hpp"
#include "io/internal/pcd.hpp"
#include "io/internal/text.hpp"
#include "io/ply_stream.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {

namespace {

namespace fs = std::filesystem;
using internal::fail;
using internal::open_input;
using internal::parse_double;
using internal::parse_long;
using internal::read_pcd;

std::string lower_extension(const fs::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

std::vector<std::string_view> split(std::string_view s) { return internal::split_whitespace(s); }

using internal::format_exact;

/// Reads the whole file as lines without comments ('#') and blank lines, with line numbers.
struct Lines {
    std::vector<std::string> text;
    std::vector<std::size_t> number;
};

Lines read_lines(const fs::path& path, bool strip_comments) {
    std::ifstream in = open_input(path);
    Lines lines;
    std::string line;
    std::size_t n = 0;
    while (std::getline(in, line)) {
        ++n;
        if (strip_comments) {
            const auto hash = line.find('#');
            if (hash != std::string::npos) line.erase(hash);
        }
        if (split(line).empty()) continue;
        lines.text.push_back(line);
        lines.number.push_back(n);
    }
    return lines;
}

Point_3 finite_point(const fs::path& path, std::size_t line, double x, double y, double z) {
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        fail(path, "line " + std::to_string(line) + ": coordinate is not finite");
    return {x, y, z};
}

std::uint8_t color_component(std::string_view token, double v) {
    // OFF/OBJ colours: integers are 0..255, decimals are 0..1.
    if (token.find_first_of(".eE") != std::string_view::npos) v *= 255.0;
    return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
}

// ------------------------------------------------------------------------------ OFF

internal::MeshSoup read_off_soup(const fs::path& path) {
    const Lines lines = read_lines(path, /*strip_comments=*/true);
    if (lines.text.empty()) fail(path, "empty file");
    auto head = split(lines.text[0]);
    std::string_view magic = head[0];
    const bool has_color = magic.find('C') != std::string_view::npos;
    const bool has_normal = magic.find('N') != std::string_view::npos;
    const bool has_tex = magic.find("ST") != std::string_view::npos;
    if (magic.size() < 3 || magic.substr(magic.size() - 3) != "OFF" ||
        magic.find('4') != std::string_view::npos || magic.find("nOFF") != std::string_view::npos)
        fail(path, "not an OFF file (header '" + std::string(magic.substr(0, 20)) + "')");
    std::size_t line = 1;
    std::vector<std::string_view> counts(head.begin() + 1, head.end());
    if (counts.empty()) {
        if (lines.text.size() < 2) fail(path, "missing vertex and face counts");
        counts = split(lines.text[1]);
        line = 2;
    }
    long long nv = 0, nf = 0;
    if (counts.size() < 2 || !parse_long(counts[0], nv) || !parse_long(counts[1], nf) || nv < 0 ||
        nf < 0)
        fail(path, "bad vertex and face counts");
    // Each count alone first: their sum can overflow.
    if (static_cast<unsigned long long>(nv) > lines.text.size() ||
        static_cast<unsigned long long>(nf) > lines.text.size() ||
        lines.text.size() < line + static_cast<std::size_t>(nv) + static_cast<std::size_t>(nf))
        fail(path, "truncated: header announces " + std::to_string(nv) + " vertices and " +
                       std::to_string(nf) + " faces, the file has fewer lines");
    internal::MeshSoup soup;
    soup.points.reserve(static_cast<std::size_t>(nv));
    for (long long i = 0; i < nv; ++i, ++line) {
        const auto t = split(lines.text[line]);
        const std::size_t ln = lines.number[line];
        const std::size_t need = 3 + (has_normal ? 3 : 0) + (has_color ? 3 : 0);
        if (t.size() < need) fail(path, "line " + std::to_string(ln) + ": too few values");
        double v[10] = {};
        for (std::size_t k = 0; k < std::min<std::size_t>(t.size(), 10); ++k)
            if (!parse_double(t[k], v[k]))
                fail(path, "line " + std::to_string(ln) + ": bad number '" +
                               std::string(t[k].substr(0, 30)) + "'");
        soup.points.push_back(finite_point(path, ln, v[0], v[1], v[2]));
        std::size_t k = 3;
        if (has_normal) {
            soup.normals.emplace_back(v[3], v[4], v[5]);
            k = 6;
        }
        if (has_color)
            soup.colors.emplace_back(color_component(t[k], v[k]),
                                     color_component(t[k + 1], v[k + 1]),
                                     color_component(t[k + 2], v[k + 2]));
        (void)has_tex;
    }
    std::vector<std::uint32_t> polygon;
    for (long long f = 0; f < nf; ++f, ++line) {
        const auto t = split(lines.text[line]);
        const std::size_t ln = lines.number[line];
        long long n = 0;
        if (!parse_long(t[0], n) || n < 0 || static_cast<std::size_t>(n) + 1 > t.size())
            fail(path, "line " + std::to_string(ln) + ": bad face");
        polygon.clear();
        for (long long k = 1; k <= n; ++k) {
            long long idx = 0;
            if (!parse_long(t[static_cast<std::size_t>(k)], idx) || idx < 0 || idx >= nv)
                fail(path, "line " + std::to_string(ln) + ": vertex index '" +
                               std::string(t[static_cast<std::size_t>(k)]) + "' out of range (" +
                               std::to_string(nv) + " vertices)");
            polygon.push_back(static_cast<std::uint32_t>(idx));
        }
        if (polygon.size() >= 3) soup.add_face(polygon);
    }
    return soup;
}

// ------------------------------------------------------------------------------ OBJ

/// Parses an OBJ index ("3", "-1") relative to `count` elements seen so far.
bool obj_index(std::string_view s, std::size_t count, std::size_t& out) {
    long long v = 0;
    if (s.empty() || !parse_long(s, v) || v == 0) return false;
    const long long idx = v > 0 ? v - 1 : static_cast<long long>(count) + v;
    if (idx < 0 || idx >= static_cast<long long>(count)) return false;
    out = static_cast<std::size_t>(idx);
    return true;
}

internal::MeshSoup read_obj_soup(const fs::path& path) {
    const Lines lines = read_lines(path, /*strip_comments=*/true);
    internal::MeshSoup soup;
    std::vector<Vector_3> normals;
    std::vector<Vector_3> vertex_normals;
    std::vector<bool> has_vertex_normal;
    bool any_color = false, any_normal = false;
    std::vector<std::uint32_t> polygon;
    for (std::size_t l = 0; l < lines.text.size(); ++l) {
        const auto t = split(lines.text[l]);
        const std::size_t ln = lines.number[l];
        const auto number = [&](std::size_t k) {
            double v = 0;
            if (k >= t.size() || !parse_double(t[k], v))
                fail(path, "line " + std::to_string(ln) + ": bad or missing number");
            return v;
        };
        if (t[0] == "v") {
            soup.points.push_back(finite_point(path, ln, number(1), number(2), number(3)));
            if (t.size() >= 7) {
                if (!any_color)
                    soup.colors.assign(soup.points.size() - 1, MeshColor(128, 128, 128));
                any_color = true;
                // OBJ vertex colours are 0..1 floats; some writers use 0..255.
                const double r = number(4), g = number(5), b = number(6);
                const double scale = std::max({r, g, b}) > 1.0 ? 1.0 : 255.0;
                const auto channel = [scale](double v) {
                    return static_cast<std::uint8_t>(std::clamp(std::lround(v * scale), 0L, 255L));
                };
                soup.colors.emplace_back(channel(r), channel(g), channel(b));
            } else if (any_color) {
                soup.colors.emplace_back(128, 128, 128);
            }
        } else if (t[0] == "vn") {
            normals.emplace_back(number(1), number(2), number(3));
        } else if (t[0] == "f") {
            polygon.clear();
            for (std::size_t k = 1; k < t.size(); ++k) {
                const std::string_view corner = t[k];
                const std::size_t s1 = corner.find('/');
                std::size_t v = 0;
                if (!obj_index(corner.substr(0, s1), soup.points.size(), v))
                    fail(path, "line " + std::to_string(ln) + ": vertex index '" +
                                   std::string(corner) + "' out of range (" +
                                   std::to_string(soup.points.size()) + " vertices so far)");
                polygon.push_back(static_cast<std::uint32_t>(v));
                if (s1 == std::string_view::npos) continue;
                const std::size_t s2 = corner.find('/', s1 + 1);
                if (s2 == std::string_view::npos) continue;
                std::size_t n = 0;
                if (s2 + 1 < corner.size()) {
                    if (!obj_index(corner.substr(s2 + 1), normals.size(), n))
                        fail(path, "line " + std::to_string(ln) + ": normal index in '" +
                                       std::string(corner) + "' out of range");
                    if (vertex_normals.size() < soup.points.size()) {
                        vertex_normals.resize(soup.points.size(), CGAL::NULL_VECTOR);
                        has_vertex_normal.resize(soup.points.size(), false);
                    }
                    vertex_normals[v] = normals[n];
                    has_vertex_normal[v] = true;
                    any_normal = true;
                }
            }
            if (polygon.size() >= 3) soup.add_face(polygon);
        }
        // vt, g, o, s, usemtl, mtllib, l, p: not needed for geometry.
    }
    if (any_normal) {
        vertex_normals.resize(soup.points.size(), CGAL::NULL_VECTOR);
        soup.normals = std::move(vertex_normals);
    }
    return soup;
}

// ------------------------------------------------------------------------------ PLY

Document read_first_ply(const fs::path& path) {
    std::ifstream in = open_input(path);
    PlyStreamReader reader(in, path.string());
    Document doc;
    if (!reader.next(doc)) fail(path, "empty file (no PLY document)");
    return doc;
}

// ------------------------------------------------------------------------------ XYZ

PointCloud read_xyz(const fs::path& path) {
    const Lines lines = read_lines(path, /*strip_comments=*/true);
    PointCloud cloud;
    std::size_t columns = 0;
    cloud.points.reserve(lines.text.size());
    for (std::size_t l = 0; l < lines.text.size(); ++l) {
        const auto t = split(lines.text[l]);
        const std::size_t ln = lines.number[l];
        if (columns == 0) {
            columns = t.size();
            if (columns != 3 && columns != 6)
                fail(path, "line " + std::to_string(ln) +
                               ": expected 3 (x y z) or 6 (x y z nx "
                               "ny nz) columns, got " +
                               std::to_string(columns));
            if (columns == 6) cloud.points.add_normal_map();
        }
        if (t.size() != columns)
            fail(path, "line " + std::to_string(ln) + ": expected " + std::to_string(columns) +
                           " columns, got " + std::to_string(t.size()));
        double v[6];
        for (std::size_t k = 0; k < columns; ++k)
            if (!parse_double(t[k], v[k]))
                fail(path, "line " + std::to_string(ln) + ": bad number '" +
                               std::string(t[k].substr(0, 30)) + "'");
        const auto idx = *cloud.points.insert(finite_point(path, ln, v[0], v[1], v[2]));
        if (columns == 6) cloud.points.normal(idx) = {v[3], v[4], v[5]};
    }
    return cloud;
}

// ------------------------------------------------------------------------------ writers

void check_point(const fs::path& path, const Point_3& p, std::size_t i) {
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z()))
        throw InputError(path.string() + ": point " + std::to_string(i) +
                         " has a non-finite coordinate; nothing written");
}

void write_off(std::ostream& out, const fs::path& path, const Mesh& mesh) {
    using V = Mesh::Vertex_index;
    const auto colors = vertex_colors(mesh);
    std::vector<std::size_t> index(mesh.num_vertices());
    std::string text = colors ? "COFF\n" : "OFF\n";
    text += std::to_string(mesh.number_of_vertices()) + " " +
            std::to_string(mesh.number_of_faces()) + " 0\n";
    std::size_t n = 0;
    for (V v : mesh.vertices()) {
        const Point_3& p = mesh.point(v);
        check_point(path, p, n);
        index[v.idx()] = n++;
        text += format_exact(p.x()) + " " + format_exact(p.y()) + " " + format_exact(p.z());
        if (colors) {
            const MeshColor c = (*colors)[v];
            text += " " + std::to_string(c.red()) + " " + std::to_string(c.green()) + " " +
                    std::to_string(c.blue()) + " 255";
        }
        text += "\n";
    }
    for (auto f : mesh.faces()) {
        std::string face;
        std::size_t count = 0;
        for (V v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
            face.push_back(' ');
            face.append(std::to_string(index[v.idx()]));
            ++count;
        }
        text += std::to_string(count) + face + "\n";
    }
    out << text;
}

void write_obj(std::ostream& out, const fs::path& path, const Mesh& mesh) {
    using V = Mesh::Vertex_index;
    const auto colors = vertex_colors(mesh);
    const auto [normals, has_normals] = mesh.property_map<V, Vector_3>(kVertexNormal);
    std::vector<std::size_t> index(mesh.num_vertices());
    std::string text = "# written by rgbd-toolkit\n";
    std::size_t n = 0;
    for (V v : mesh.vertices()) {
        const Point_3& p = mesh.point(v);
        check_point(path, p, n);
        index[v.idx()] = ++n;
        text += "v " + format_exact(p.x()) + " " + format_exact(p.y()) + " " + format_exact(p.z());
        if (colors) {
            const MeshColor c = (*colors)[v];
            text += " " + format_exact(c.red() / 255.0) + " " + format_exact(c.green() / 255.0) +
                    " " + format_exact(c.blue() / 255.0);
        }
        text += "\n";
    }
    if (has_normals)
        for (V v : mesh.vertices()) {
            const Vector_3& nv = normals[v];
            text += "vn " + format_exact(nv.x()) + " " + format_exact(nv.y()) + " " +
                    format_exact(nv.z()) + "\n";
        }
    for (auto f : mesh.faces()) {
        text += "f";
        for (V v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
            const std::string i = std::to_string(index[v.idx()]);
            text += " " + (has_normals ? i + "//" + i : i);
        }
        text += "\n";
    }
    out << text;
}

}  // namespace

Mesh read_mesh(const fs::path& path) {
    const std::string ext = lower_extension(path);
    Mesh mesh;
    if (ext == ".ply") {
        Document doc = read_first_ply(path);
        if (doc.kind != DocumentKind::kMesh) fail(path, "a point cloud, not a mesh (no faces)");
        mesh = std::move(doc.mesh);
    } else if (ext == ".off") {
        internal::build_mesh(read_off_soup(path), mesh);
    } else if (ext == ".obj") {
        internal::build_mesh(read_obj_soup(path), mesh);
    } else {
        fail(path, "unsupported mesh format '" + ext + "' (expected .ply, .off or .obj)");
    }
    if (mesh.number_of_faces() == 0) fail(path, "mesh has no faces");
    return mesh;
}

void write_mesh(const fs::path& path, const Mesh& mesh, const ViewInfo* view) {
    const std::string ext = lower_extension(path);
    if (ext != ".ply" && ext != ".off" && ext != ".obj")
        throw InputError(path.string() + ": unsupported mesh format '" + ext +
                         "' (expected .ply, .off or .obj)");
    internal::write_file_atomic(path, [&](std::ostream& out) {
        if (ext == ".ply") {
            try {
                io::write_mesh(out, mesh, view ? *view : ViewInfo{});
            } catch (const InputError& e) {
                throw InputError(path.string() + ": " + e.what());
            }
        } else if (ext == ".off") {
            write_off(out, path, mesh);
        } else {
            write_obj(out, path, mesh);
        }
    });
}

PointCloud read_point_cloud(const fs::path& path) {
    const std::string ext = lower_extension(path);
    if (ext == ".ply") {
        Document doc = read_first_ply(path);
        if (doc.kind == DocumentKind::kPoints) return std::move(doc.cloud);
        // A mesh document: its vertices, with colours and normals.
        internal::MeshSoup soup;
        const auto colors = vertex_colors(doc.mesh);
        const auto [normals, has_normals] =
            doc.mesh.property_map<Mesh::Vertex_index, Vector_3>(kVertexNormal);
        for (auto v : doc.mesh.vertices()) {
            soup.points.push_back(doc.mesh.point(v));
            if (colors) soup.colors.push_back((*colors)[v]);
            if (has_normals) soup.normals.push_back(normals[v]);
        }
        PointCloud cloud;
        internal::soup_to_cloud(soup, cloud);
        cloud.view = doc.cloud.view;
        return cloud;
    }
    PointCloud cloud;
    if (ext == ".xyz" || ext == ".pwn") return read_xyz(path);
    if (ext == ".pcd") return read_pcd(path);
    if (ext == ".off") {
        internal::soup_to_cloud(read_off_soup(path), cloud);
    } else if (ext == ".obj") {
        internal::soup_to_cloud(read_obj_soup(path), cloud);
    } else {
        fail(path, "unsupported point cloud format '" + ext +
                       "' (expected .ply, .xyz, .pwn, .pcd, .off or .obj)");
    }
    return cloud;
}

void write_point_cloud(const fs::path& path, const PointCloud& cloud) {
    const std::string ext = lower_extension(path);
    if (ext != ".ply" && ext != ".xyz")
        throw InputError(path.string() + ": unsupported point cloud format '" + ext +
                         "' (expected .ply or .xyz)");
    internal::write_file_atomic(path, [&](std::ostream& out) {
        if (ext == ".ply") {
            try {
                write_points(out, cloud);
            } catch (const InputError& e) {
                throw InputError(path.string() + ": " + e.what());
            }
            return;
        }
        const bool normals = cloud.points.has_normal_map();
        std::string text;
        std::size_t i = 0;
        for (auto idx : cloud.points) {
            const Point_3& p = cloud.points.point(idx);
            check_point(path, p, i++);
            text += format_exact(p.x()) + " " + format_exact(p.y()) + " " + format_exact(p.z());
            if (normals) {
                const Vector_3& n = cloud.points.normal(idx);
                text += " " + format_exact(n.x()) + " " + format_exact(n.y()) + " " +
                        format_exact(n.z());
            }
            text += "\n";
            if (text.size() > (1u << 20)) {
                out << text;
                text.clear();
            }
        }
        out << text;
    });
}

}  // namespace rgbd::io
