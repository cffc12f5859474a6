#include "io/ply_stream.hpp"

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
#include "toolkit/error.hpp"
namespace rgbd::io {

static_assert(std::endian::native == std::endian::little,
              "the PLY reader assumes a little-endian host");

namespace {

using namespace internal::ply;

// ---------------------------------------------------------------------------------------
// The document parser

class DocumentParser {
public:
    DocumentParser(std::istream& in, const std::string& name, std::size_t index)
        : in_(in), name_(name), index_(index) {}

    [[noreturn]] void fail(const std::string& problem) const {
        throw InputError(name_ + ": document " + std::to_string(index_) + ": " + problem);
    }

    /// Skips whitespace; false at EOF.
    bool at_document() {
        while (true) {
            const int c = in_.peek();
            if (c == std::char_traits<char>::eof()) return false;
            if (c == ' ' || c == '\t' || c == '\r' || c == '\n') {
                in_.get();
                continue;
            }
            return true;
        }
    }

    Header read_header() {
        Header header;
        std::string line;
        if (!read_line(line) || trim(line) != "ply") {
            std::string start = line.substr(0, 20);
            for (char& c : start)
                if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126)
                    c = '?';
            fail("not a PLY document (starts with '" + start + "')");
        }
        bool have_format = false;
        std::size_t lines = 0;
        while (true) {
            if (!read_line(line)) fail("truncated header (no end_header)");
            if (++lines > 100000) fail("header too long");
            const std::string_view text = trim(line);
            if (text.empty()) continue;
            const auto tokens = split(text);
            const std::string_view key = tokens[0];
            if (key == "end_header") break;
            if (key == "comment") {
                // Keep the text verbatim after "comment ".
                std::string_view rest = std::string_view(line).substr(line.find("comment") + 7);
                if (!rest.empty() && (rest.front() == ' ' || rest.front() == '\t'))
                    rest.remove_prefix(1);
                while (!rest.empty() && (rest.back() == '\r' || rest.back() == '\n'))
                    rest.remove_suffix(1);
                header.comments.emplace_back(rest);
            } else if (key == "obj_info") {
                continue;
            } else if (key == "format") {
                if (tokens.size() != 3) fail("malformed format line '" + std::string(text) + "'");
                if (tokens[2] != "1.0")
                    fail("unsupported PLY version '" + std::string(tokens[2]) + "'");
                if (tokens[1] == "ascii") {
                    header.format = Format::kAscii;
                } else if (tokens[1] == "binary_little_endian") {
                    header.format = Format::kBinaryLittle;
                } else if (tokens[1] == "binary_big_endian") {
                    header.format = Format::kBinaryBig;
                } else {
                    fail("unsupported format '" + std::string(tokens[1]) + "'");
                }
                have_format = true;
            } else if (key == "element") {
                if (tokens.size() != 3) fail("malformed element line '" + std::string(text) + "'");
                Element e;
                e.name = std::string(tokens[1]);
                const auto count = parse_int<std::uint64_t>(tokens[2]);
                if (!count) fail("bad element count in '" + std::string(text) + "'");
                e.count = static_cast<std::size_t>(*count);
                header.elements.push_back(std::move(e));
            } else if (key == "property") {
                if (header.elements.empty()) fail("property before any element");
                Element& e = header.elements.back();
                Property p;
                if (tokens.size() == 5 && tokens[1] == "list") {
                    const auto ct = parse_type(tokens[2]);
                    const auto vt = parse_type(tokens[3]);
                    if (!ct || !vt || !is_integer(*ct))
                        fail("bad list property '" + std::string(text) + "'");
                    p.is_list = true;
                    p.count_type = *ct;
                    p.type = *vt;
                    p.name = std::string(tokens[4]);
                    p.offset = e.list_count++;
                } else if (tokens.size() == 3) {
                    const auto t = parse_type(tokens[1]);
                    if (!t) fail("unknown property type in '" + std::string(text) + "'");
                    p.type = *t;
                    p.name = std::string(tokens[2]);
                    p.offset = e.stride;
                    e.stride += type_size(*t);
                } else {
                    fail("malformed property line '" + std::string(text) + "'");
                }
                e.props.push_back(std::move(p));
            } else {
                fail("unexpected header line '" + std::string(text.substr(0, 60)) + "'");
            }
        }
        if (!have_format) fail("header has no format line");
        return header;
    }

    void read_data(Header& header) {
        for (Element& e : header.elements) {
            // Instances without properties would read nothing, so any count (up to 2^64)
            // would "succeed": a loop without end on garbage.
            if (e.count > 0 && e.props.empty())
                fail("element '" + e.name + "' has " + std::to_string(e.count) +
                     " instances but no properties");
            e.lists.assign(e.list_count, ListData{});
            if (header.format == Format::kAscii) {
                read_ascii(e);
            } else {
                read_binary(e, header.format == Format::kBinaryBig);
            }
        }
    }

private:
    /// Reads one header line (up to 64 KiB) without reading past its newline.
    bool read_line(std::string& line) {
        line.clear();
        char c;
        while (in_.get(c)) {
            if (c == '\n') return true;
            line.push_back(c);
            if (line.size() > 65536) fail("header line too long (not a PLY header)");
        }
        return !line.empty();
    }

    [[noreturn]] void truncated(const Element& e, std::size_t done) const {
        fail("truncated data: element '" + e.name + "' has " + std::to_string(done) + " of " +
             std::to_string(e.count) + " instances");
    }

    static void swap_bytes(unsigned char* p, std::size_t n) { std::reverse(p, p + n); }

    /// Rows allocated before any data is read; the buffer doubles as data arrives, so a
    /// bogus count in a short document cannot allocate much (the stride can be kilobytes).
    static constexpr std::size_t kFirstRows = std::size_t{1} << 12;

    void read_binary(Element& e, bool big_endian) {
        const std::size_t list_props = e.list_count;
        if (list_props == 0) {
            // One block read, in chunks so that a bogus count cannot allocate unbounded memory.
            const std::size_t total = e.count * e.stride;
            if (e.stride != 0 && total / e.stride != e.count) fail("element count too large");
            constexpr std::size_t kChunk = std::size_t{64} << 20;
            std::size_t done = 0;
            while (done < total) {
                const std::size_t n = std::min(kChunk, total - done);
                e.rows.resize(done + n);
                in_.read(reinterpret_cast<char*>(e.rows.data() + done),
                         static_cast<std::streamsize>(n));
                const auto got = static_cast<std::size_t>(in_.gcount());
                if (got != n) truncated(e, (done + got) / e.stride);
                done += n;
            }
            if (big_endian)
                for (std::size_t i = 0; i < e.count; ++i)
                    for (const Property& p : e.props)
                        swap_bytes(e.rows.data() + i * e.stride + p.offset, type_size(p.type));
            return;
        }
        e.rows.resize(std::min<std::size_t>(e.count, kFirstRows) * e.stride);
        std::vector<unsigned char> buf;
        for (std::size_t i = 0; i < e.count; ++i) {
            if ((i + 1) * e.stride > e.rows.size()) e.rows.resize((i + 1) * e.stride * 2);
            unsigned char* row = e.rows.data() + i * e.stride;
            for (const Property& p : e.props) {
                if (!p.is_list) {
                    const std::size_t n = type_size(p.type);
                    if (!in_.read(reinterpret_cast<char*>(row + p.offset),
                                  static_cast<std::streamsize>(n)))
                        truncated(e, i);
                    if (big_endian) swap_bytes(row + p.offset, n);
                    continue;
                }
                unsigned char cbuf[8];
                const std::size_t cn = type_size(p.count_type);
                if (!in_.read(reinterpret_cast<char*>(cbuf), static_cast<std::streamsize>(cn)))
                    truncated(e, i);
                if (big_endian) swap_bytes(cbuf, cn);
                const double count = read_value(cbuf, p.count_type);
                if (count < 0 || count > 1e6)
                    fail("element '" + e.name + "' instance " + std::to_string(i) +
                         ": bad list length " + format_double(count));
                const std::size_t vn = type_size(p.type);
                const auto len = static_cast<std::size_t>(count);
                buf.resize(len * vn);
                if (len > 0 && !in_.read(reinterpret_cast<char*>(buf.data()),
                                         static_cast<std::streamsize>(buf.size())))
                    truncated(e, i);
                ListData& list = e.lists[p.offset];
                for (std::size_t k = 0; k < len; ++k) {
                    if (big_endian) swap_bytes(buf.data() + k * vn, vn);
                    list.values.push_back(read_value(buf.data() + k * vn, p.type));
                }
                list.offsets.push_back(list.values.size());
            }
        }
        e.rows.resize(e.count * e.stride);
    }

    bool next_token(std::string_view& token) {
        while (pos_ >= tokens_.size()) {
            if (!std::getline(in_, ascii_line_)) return false;
            tokens_ = split(ascii_line_);
            pos_ = 0;
        }
        token = tokens_[pos_++];
        return true;
    }

    double ascii_number(const Element& e, std::size_t i, PlyType t) {
        std::string_view token;
        if (!next_token(token)) truncated(e, i);
        const auto v = parse_double(token);
        if (!v)
            fail("element '" + e.name + "' instance " + std::to_string(i) + ": bad number '" +
                 std::string(token.substr(0, 30)) + "'");
        if (is_integer(t) && (!fits(t, *v) || *v != std::floor(*v)))
            fail("element '" + e.name + "' instance " + std::to_string(i) + ": value '" +
                 std::string(token.substr(0, 30)) + "' does not fit type " + type_name(t));
        return *v;
    }

    void read_ascii(Element& e) {
        e.rows.assign(std::min<std::size_t>(e.count, kFirstRows) * e.stride, 0);
        for (std::size_t i = 0; i < e.count; ++i) {
            if ((i + 1) * e.stride > e.rows.size()) e.rows.resize((i + 1) * e.stride * 2);
            unsigned char* row = e.rows.data() + i * e.stride;
            for (const Property& p : e.props) {
                if (!p.is_list) {
                    write_value(row + p.offset, p.type, ascii_number(e, i, p.type));
                    continue;
                }
                const double count = ascii_number(e, i, p.count_type);
                if (count < 0 || count > 1e6)
                    fail("element '" + e.name + "' instance " + std::to_string(i) +
                         ": bad list length");
                ListData& list = e.lists[p.offset];
                for (std::size_t k = 0; k < static_cast<std::size_t>(count); ++k)
                    list.values.push_back(ascii_number(e, i, p.type));
                list.offsets.push_back(list.values.size());
            }
            // An element instance ends its line: ignore trailing tokens of that line.
            pos_ = tokens_.size();
        }
        e.rows.resize(e.count * e.stride);
    }

    std::istream& in_;
    const std::string& name_;
    std::size_t index_;
    std::string ascii_line_;
    std::vector<std::string_view> tokens_;
    std::size_t pos_ = 0;
};

// ---------------------------------------------------------------------------------------
// Conversion of parsed elements into points / meshes

bool is_reserved_vertex_property(std::string_view n) {
    return n == "x" || n == "y" || n == "z" || n == "nx" || n == "ny" || n == "nz" || n == "red" ||
           n == "green" || n == "blue" || n == "alpha" || n == "diffuse_red" ||
           n == "diffuse_green" || n == "diffuse_blue" || n == "index" || n == "point" ||
           n == "normal";
}

std::uint8_t to_color(double v, PlyType t) {
    if (!is_integer(t)) v = v <= 1.0 ? v * 255.0 : v;  // float colours are 0..1 by convention
    if (!(v > 0)) return 0;
    if (v >= 255) return 255;
    return static_cast<std::uint8_t>(std::lround(v));
}

template <typename T>
void add_column(PointSet& points, const Element& e, const Property& p) {
    auto [map, created] = points.add_property_map<T>(p.name, T{});
    if (!created) return;
    for (std::size_t i = 0; i < e.count; ++i)
        map[PointSet::Index(static_cast<PointSet::Index::size_type>(i))] =
            static_cast<T>(e.value(i, p));
}

void add_typed_column(PointSet& points, const Element& e, const Property& p, PlyType as) {
    visit_type(as, [&]<typename T>() { add_column<T>(points, e, p); });
}

std::optional<PlyType> known_property_type(std::string_view n) {
    if (n == prop::kPixel) return PlyType::kUint32;
    if (n == prop::kView) return PlyType::kInt32;
    if (n == prop::kConfidence || n == prop::kScale) return PlyType::kFloat32;
    if (n == prop::kNoise || n == prop::kSynthetic) return PlyType::kUint8;
    return std::nullopt;
}

struct VertexColumns {
    const Property* x = nullptr;
    const Property* y = nullptr;
    const Property* z = nullptr;
    const Property* nx = nullptr;
    const Property* ny = nullptr;
    const Property* nz = nullptr;
    const Property* r = nullptr;
    const Property* g = nullptr;
    const Property* b = nullptr;
};

VertexColumns vertex_columns(const Element& v, const DocumentParser& parser) {
    VertexColumns c;
    c.x = v.find("x");
    c.y = v.find("y");
    c.z = v.find("z");
    if (!c.x || !c.y || !c.z || c.x->is_list || c.y->is_list || c.z->is_list)
        parser.fail("vertex element has no scalar x, y, z properties");
    c.nx = v.find("nx");
    c.ny = v.find("ny");
    c.nz = v.find("nz");
    if (!c.nx || !c.ny || !c.nz || c.nx->is_list || c.ny->is_list || c.nz->is_list)
        c.nx = c.ny = c.nz = nullptr;
    c.r = v.find("red");
    c.g = v.find("green");
    c.b = v.find("blue");
    if (!c.r || !c.g || !c.b) {
        c.r = v.find("diffuse_red");
        c.g = v.find("diffuse_green");
        c.b = v.find("diffuse_blue");
    }
    if (!c.r || !c.g || !c.b || c.r->is_list || c.g->is_list || c.b->is_list)
        c.r = c.g = c.b = nullptr;
    return c;
}

Point_3 vertex_point(const Element& v, const VertexColumns& c, std::size_t i,
                     const DocumentParser& parser) {
    const double x = v.value(i, *c.x), y = v.value(i, *c.y), z = v.value(i, *c.z);
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
        parser.fail("vertex " + std::to_string(i) + ": coordinate is not finite");
    return {x, y, z};
}

void build_points(const Element& v, PointCloud& cloud, const DocumentParser& parser) {
    const VertexColumns c = vertex_columns(v, parser);
    PointSet& points = cloud.points;
    points.clear();
    if (c.nx) points.add_normal_map();
    points.resize(v.count);
    // Fast paths for the common layouts: three consecutive doubles or floats.
    const auto triple = [](const Property* a, const Property* b, const Property* d) {
        if (a->type != b->type || b->type != d->type) return 0;
        const std::size_t n = type_size(a->type);
        if (b->offset != a->offset + n || d->offset != b->offset + n) return 0;
        return a->type == PlyType::kFloat64 ? 8 : a->type == PlyType::kFloat32 ? 4 : 0;
    };
    const auto load3 = [&v](std::size_t i, const Property* a, int kind, double out[3]) {
        const unsigned char* p = v.rows.data() + i * v.stride + a->offset;
        if (kind == 8) {
            std::memcpy(out, p, 24);
        } else {
            float f[3];
            std::memcpy(f, p, 12);
            out[0] = f[0];
            out[1] = f[1];
            out[2] = f[2];
        }
    };
    const int xyz_kind = triple(c.x, c.y, c.z);
    const int n_kind = c.nx ? triple(c.nx, c.ny, c.nz) : 0;
    PointSet::Point_map point_map = points.point_map();
    for (std::size_t i = 0; i < v.count; ++i) {
        const PointSet::Index idx(static_cast<PointSet::Index::size_type>(i));
        if (xyz_kind != 0) {
            double q[3];
            load3(i, c.x, xyz_kind, q);
            if (!std::isfinite(q[0]) || !std::isfinite(q[1]) || !std::isfinite(q[2]))
                parser.fail("vertex " + std::to_string(i) + ": coordinate is not finite");
            point_map[idx] = Point_3(q[0], q[1], q[2]);
        } else {
            point_map[idx] = vertex_point(v, c, i, parser);
        }
        if (!c.nx) continue;
        if (n_kind != 0) {
            double q[3];
            load3(i, c.nx, n_kind, q);
            points.normal(idx) = Vector_3(q[0], q[1], q[2]);
        } else {
            points.normal(idx) = {v.value(i, *c.nx), v.value(i, *c.ny), v.value(i, *c.nz)};
        }
    }
    // Properties in file order, colours as uint8 where they first appear.
    bool colors_added = false;
    for (const Property& p : v.props) {
        if (p.is_list) continue;
        if (c.r && (&p == c.r || &p == c.g || &p == c.b)) {
            if (colors_added) continue;
            colors_added = true;
            const auto maps = cloud.add_colors();
            if (c.r->type == PlyType::kUint8 && c.g->type == PlyType::kUint8 &&
                c.b->type == PlyType::kUint8) {
                for (std::size_t i = 0; i < v.count; ++i) {
                    const unsigned char* row = v.rows.data() + i * v.stride;
                    const PointSet::Index idx(static_cast<PointSet::Index::size_type>(i));
                    maps.r[idx] = row[c.r->offset];
                    maps.g[idx] = row[c.g->offset];
                    maps.b[idx] = row[c.b->offset];
                }
                continue;
            }
            for (std::size_t i = 0; i < v.count; ++i)
                maps.set(
                    PointSet::Index(static_cast<PointSet::Index::size_type>(i)),
                    {to_color(v.value(i, *c.r), c.r->type), to_color(v.value(i, *c.g), c.g->type),
                     to_color(v.value(i, *c.b), c.b->type)});
            continue;
        }
        if (is_reserved_vertex_property(p.name)) continue;
        add_typed_column(points, v, p, known_property_type(p.name).value_or(p.type));
    }
}

void build_mesh_document(const Header& header, const Element& v, Mesh& mesh,
                         const DocumentParser& parser) {
    const VertexColumns c = vertex_columns(v, parser);
    internal::MeshSoup soup;
    soup.points.reserve(v.count);
    for (std::size_t i = 0; i < v.count; ++i) {
        soup.points.push_back(vertex_point(v, c, i, parser));
        if (c.r)
            soup.colors.emplace_back(to_color(v.value(i, *c.r), c.r->type),
                                     to_color(v.value(i, *c.g), c.g->type),
                                     to_color(v.value(i, *c.b), c.b->type));
        if (c.nx)
            soup.normals.emplace_back(v.value(i, *c.nx), v.value(i, *c.ny), v.value(i, *c.nz));
    }
    for (const Element& f : header.elements) {
        if (f.name != "face") continue;
        const Property* list = f.find("vertex_indices");
        if (!list) list = f.find("vertex_index");
        if (!list || !list->is_list) parser.fail("face element has no vertex_indices list");
        const ListData& data = f.lists[list->offset];
        std::vector<std::uint32_t> polygon;
        for (std::size_t k = 0; k < f.count; ++k) {
            polygon.clear();
            for (std::size_t j = data.offsets[k]; j < data.offsets[k + 1]; ++j) {
                const double index = data.values[j];
                if (!(index >= 0 && index < static_cast<double>(v.count)))
                    parser.fail("face " + std::to_string(k) + ": vertex index " +
                                format_double(index) + " out of range (" + std::to_string(v.count) +
                                " vertices)");
                polygon.push_back(static_cast<std::uint32_t>(index));
            }
            if (polygon.size() >= 3) soup.add_face(polygon);
        }
    }
    internal::build_mesh(soup, mesh);
}

}  // namespace

PlyStreamReader::PlyStreamReader(std::istream& in, std::string name)
    : in_(in), name_(std::move(name)) {}

bool PlyStreamReader::next(Document& document) {
    DocumentParser parser(in_, name_, count_ + 1);
    if (!parser.at_document()) return false;
    Header header = parser.read_header();
    parser.read_data(header);

    const Element* vertex = nullptr;
    bool has_face = false;
    for (const Element& e : header.elements) {
        if (e.name == "vertex" && !vertex) vertex = &e;
        if (e.name == "face") has_face = true;
    }
    if (!vertex) parser.fail("header has no vertex element");

    bool kind_mesh = has_face;
    for (const std::string& c : header.comments)
        if (trim(c) == "rgbd:kind mesh") kind_mesh = true;

    Document doc;
    try {
        doc.cloud.view = view_from_comments(header.comments);
    } catch (const InputError& e) {
        parser.fail(e.what());
    }
    if (kind_mesh) {
        doc.kind = DocumentKind::kMesh;
        build_mesh_document(header, *vertex, doc.mesh, parser);
    } else {
        doc.kind = DocumentKind::kPoints;
        build_points(*vertex, doc.cloud, parser);
    }
    document = std::move(doc);
    ++count_;
    return true;
}

}  // namespace rgbd::io
