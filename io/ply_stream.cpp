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

#include "io/internal/text.hpp"
#include "io/internal/mesh_soup.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io {

static_assert(std::endian::native == std::endian::little,
              "the PLY reader assumes a little-endian host");

namespace {

// ---------------------------------------------------------------------------------------
// Small text helpers

std::string_view trim(std::string_view s) {
    const auto not_space = [](char c) { return c != ' ' && c != '\t' && c != '\r' && c != '\n'; };
    while (!s.empty() && !not_space(s.front())) s.remove_prefix(1);
    while (!s.empty() && !not_space(s.back())) s.remove_suffix(1);
    return s;
}

std::vector<std::string_view> split(std::string_view s) { return internal::split_whitespace(s); }

std::optional<double> parse_double(std::string_view s) {
    double v = 0;
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || ptr != s.data() + s.size()) return std::nullopt;
    return v;
}

template <typename Int>
std::optional<Int> parse_int(std::string_view s) {
    Int v = 0;
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || ptr != s.data() + s.size()) return std::nullopt;
    return v;
}

std::string format_double(double v) {
    char buf[64];
    const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::general, 17);
    return std::string(buf, ptr);
}

// ---------------------------------------------------------------------------------------
// PLY types

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::optional<PlyType> parse_type(std::string_view s) {
    if (s == "char" || s == "int8") return PlyType::kInt8;
    if (s == "uchar" || s == "uint8") return PlyType::kUint8;
    if (s == "short" || s == "int16") return PlyType::kInt16;
    if (s == "ushort" || s == "uint16") return PlyType::kUint16;
    if (s == "int" || s == "int32") return PlyType::kInt32;
    if (s == "uint" || s == "uint32") return PlyType::kUint32;
    if (s == "float" || s == "float32") return PlyType::kFloat32;
    if (s == "double" || s == "float64") return PlyType::kFloat64;
    return std::nullopt;
}

const char* type_name(PlyType t) {
    switch (t) {
        case PlyType::kInt8:
            return "char";
        case PlyType::kUint8:
            return "uchar";
        case PlyType::kInt16:
            return "short";
        case PlyType::kUint16:
            return "ushort";
        case PlyType::kInt32:
            return "int";
        case PlyType::kUint32:
            return "uint";
        case PlyType::kFloat32:
            return "float";
        case PlyType::kFloat64:
            return "double";
    }
    return "?";
}

std::size_t type_size(PlyType t) {
    switch (t) {
        case PlyType::kInt8:
        case PlyType::kUint8:
            return 1;
        case PlyType::kInt16:
        case PlyType::kUint16:
            return 2;
        case PlyType::kInt32:
        case PlyType::kUint32:
        case PlyType::kFloat32:
            return 4;
        case PlyType::kFloat64:
            return 8;
    }
    return 0;
}

bool is_integer(PlyType t) { return t != PlyType::kFloat32 && t != PlyType::kFloat64; }

template <typename T>
T load(const unsigned char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}

double read_value(const unsigned char* p, PlyType t) {
    switch (t) {
        case PlyType::kInt8:
            return load<std::int8_t>(p);
        case PlyType::kUint8:
            return load<std::uint8_t>(p);
        case PlyType::kInt16:
            return load<std::int16_t>(p);
        case PlyType::kUint16:
            return load<std::uint16_t>(p);
        case PlyType::kInt32:
            return load<std::int32_t>(p);
        case PlyType::kUint32:
            return load<std::uint32_t>(p);
        case PlyType::kFloat32:
            return load<float>(p);
        case PlyType::kFloat64:
            return load<double>(p);
    }
    return 0;
}

template <typename T>
void store(unsigned char* p, double v) {
    const T t = static_cast<T>(v);
    std::memcpy(p, &t, sizeof(T));
}

void write_value(unsigned char* p, PlyType t, double v) {
    switch (t) {
        case PlyType::kInt8:
            store<std::int8_t>(p, v);
            break;
        case PlyType::kUint8:
            store<std::uint8_t>(p, v);
            break;
        case PlyType::kInt16:
            store<std::int16_t>(p, v);
            break;
        case PlyType::kUint16:
            store<std::uint16_t>(p, v);
            break;
        case PlyType::kInt32:
            store<std::int32_t>(p, v);
            break;
        case PlyType::kUint32:
            store<std::uint32_t>(p, v);
            break;
        case PlyType::kFloat32:
            store<float>(p, v);
            break;
        case PlyType::kFloat64:
            store<double>(p, v);
            break;
    }
}

/// Range of an integer type, to reject out-of-range ASCII values.
bool fits(PlyType t, double v) {
    switch (t) {
        case PlyType::kInt8:
            return v >= -128 && v <= 127;
        case PlyType::kUint8:
            return v >= 0 && v <= 255;
        case PlyType::kInt16:
            return v >= -32768 && v <= 32767;
        case PlyType::kUint16:
            return v >= 0 && v <= 65535;
        case PlyType::kInt32:
            return v >= -2147483648.0 && v <= 2147483647.0;
        case PlyType::kUint32:
            return v >= 0 && v <= 4294967295.0;
        default:
            return true;
    }
}

// ---------------------------------------------------------------------------------------
// Header and element storage

enum class Format { kAscii, kBinaryLittle, kBinaryBig };

struct Property {
    std::string name;
    PlyType type = PlyType::kFloat32;
    bool is_list = false;
    PlyType count_type = PlyType::kUint8;
    std::size_t offset = 0;  ///< scalar: byte offset in the row; list: index into lists
};

struct ListData {
    std::vector<std::size_t> offsets{0};
    std::vector<double> values;
};

struct Element {
    std::string name;
    std::size_t count = 0;
    std::vector<Property> props;
    std::size_t stride = 0;  ///< bytes of the scalar properties of one instance
    std::size_t list_count = 0;
    std::vector<unsigned char> rows;  ///< count * stride, little-endian
    std::vector<ListData> lists;

    const Property* find(std::string_view n) const {
        for (const Property& p : props)
            if (p.name == n) return &p;
        return nullptr;
    }
    double value(std::size_t i, const Property& p) const {
        return read_value(rows.data() + i * stride + p.offset, p.type);
    }
};

struct Header {
    Format format = Format::kBinaryLittle;
    std::vector<std::string> comments;
    std::vector<Element> elements;
};

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
        e.rows.resize(std::min<std::size_t>(e.count, std::size_t{1} << 24) * e.stride);
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
        e.rows.assign(std::min<std::size_t>(e.count, std::size_t{1} << 24) * e.stride, 0);
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
    switch (as) {
        case PlyType::kInt8:
            add_column<std::int8_t>(points, e, p);
            break;
        case PlyType::kUint8:
            add_column<std::uint8_t>(points, e, p);
            break;
        case PlyType::kInt16:
            add_column<std::int16_t>(points, e, p);
            break;
        case PlyType::kUint16:
            add_column<std::uint16_t>(points, e, p);
            break;
        case PlyType::kInt32:
            add_column<std::int32_t>(points, e, p);
            break;
        case PlyType::kUint32:
            add_column<std::uint32_t>(points, e, p);
            break;
        case PlyType::kFloat32:
            add_column<float>(points, e, p);
            break;
        case PlyType::kFloat64:
            add_column<double>(points, e, p);
            break;
    }
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
    const auto triple = [&v](const Property* a, const Property* b, const Property* d) {
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

// ---------------------------------------------------------------------------------------
// Writing

std::string pose_text(const Pose& pose) {
    std::string s;
    for (double v : pose_to_3x4(pose)) s += " " + format_double(v);
    return s;
}

std::string one_line(std::string s) {
    for (char& c : s)
        if (c == '\n' || c == '\r') c = ' ';
    return s;
}

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
    auto [map, found] = points.property_map<T>(name);
    if (!found) return false;
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

// -----------------------------------------------------------------------------------------

std::vector<std::string> view_to_comments(const ViewInfo& view, DocumentKind kind) {
    std::vector<std::string> c;
    c.push_back("rgbd:stream 1");
    c.push_back(std::string("rgbd:kind ") + (kind == DocumentKind::kMesh ? "mesh" : "points"));
    c.push_back("rgbd:units m");
    if (view.id != -1) c.push_back("rgbd:view.id " + std::to_string(view.id));
    if (!view.sensor.empty()) c.push_back("rgbd:view.sensor " + one_line(view.sensor));
    if (view.time_ns) c.push_back("rgbd:view.time_ns " + std::to_string(*view.time_ns));
    if (view.frame_index)
        c.push_back("rgbd:view.frame_index " + std::to_string(*view.frame_index));
    c.push_back(std::string("rgbd:view.frame ") +
                (view.frame == ViewFrame::kWorld ? "world" : "sensor"));
    if (view.intrinsics) {
        const PinholeIntrinsics& k = *view.intrinsics;
        c.push_back("rgbd:camera.intrinsics " + std::to_string(k.width) + " " +
                    std::to_string(k.height) + " " + format_double(k.fx) + " " +
                    format_double(k.fy) + " " + format_double(k.cx) + " " + format_double(k.cy));
        if (k.distortion.model != "none" || !k.distortion.coeffs.empty()) {
            std::string d = "rgbd:camera.distortion " + one_line(k.distortion.model);
            for (double v : k.distortion.coeffs) d += " " + format_double(v);
            c.push_back(d);
        }
    }
    if (view.world_from_sensor)
        c.push_back("rgbd:pose.world_from_sensor" + pose_text(*view.world_from_sensor));
    if (view.grid_width != 0 || view.grid_height != 0)
        c.push_back("rgbd:grid " + std::to_string(view.grid_width) + " " +
                    std::to_string(view.grid_height));
    if (!view.source.empty()) c.push_back("rgbd:view.source " + one_line(view.source));
    for (const std::string& h : view.history) c.push_back("rgbd:history " + one_line(h));
    for (const std::string& e : view.extra_comments) c.push_back(one_line(e));
    return c;
}

ViewInfo view_from_comments(const std::vector<std::string>& comments) {
    ViewInfo view;
    std::optional<Distortion> distortion;
    for (const std::string& line : comments) {
        const std::string_view text = line;
        if (text.substr(0, 5) != "rgbd:") {
            view.extra_comments.push_back(line);
            continue;
        }
        const std::size_t space = text.find_first_of(" \t");
        const std::string_view key = text.substr(0, space);
        const std::string_view rest =
            space == std::string_view::npos ? std::string_view() : trim(text.substr(space + 1));
        // Single-string values keep inner spaces; only the one separator is removed.
        const std::string_view raw_rest =
            space == std::string_view::npos ? std::string_view() : text.substr(space + 1);
        const auto values = split(rest);
        const auto bad = [&](const std::string& why) -> InputError {
            return InputError("malformed comment '" + line.substr(0, 80) + "': " + why);
        };
        const auto number = [&](std::size_t i) {
            const auto v = parse_double(values[i]);
            if (!v || !std::isfinite(*v))
                throw bad("'" + std::string(values[i]) + "' is not a number");
            return *v;
        };
        const auto integer = [&](std::size_t i) {
            const auto v = parse_int<std::int64_t>(values[i]);
            if (!v) throw bad("'" + std::string(values[i]) + "' is not an integer");
            return *v;
        };
        const auto expect = [&](std::size_t n) {
            if (values.size() != n)
                throw bad("expected " + std::to_string(n) + " values, got " +
                          std::to_string(values.size()));
        };
        if (key == "rgbd:stream") {
            expect(1);
            if (integer(0) != 1)
                throw bad("unsupported stream version (this reader knows rgbd:stream 1)");
        } else if (key == "rgbd:kind") {
            expect(1);
            if (values[0] != "points" && values[0] != "mesh") throw bad("kind is points or mesh");
        } else if (key == "rgbd:units") {
            expect(1);
            if (values[0] != "m") throw bad("only metres (m) are supported");
        } else if (key == "rgbd:view.id") {
            expect(1);
            const auto id = integer(0);
            if (id < -1 || id > std::numeric_limits<int>::max()) throw bad("id out of range");
            view.id = static_cast<int>(id);
        } else if (key == "rgbd:view.sensor") {
            view.sensor = std::string(raw_rest);
        } else if (key == "rgbd:view.time_ns") {
            expect(1);
            view.time_ns = integer(0);
        } else if (key == "rgbd:view.frame_index") {
            expect(1);
            view.frame_index = integer(0);
        } else if (key == "rgbd:view.frame") {
            expect(1);
            if (values[0] == "sensor") {
                view.frame = ViewFrame::kSensor;
            } else if (values[0] == "world") {
                view.frame = ViewFrame::kWorld;
            } else {
                throw bad("frame is sensor or world");
            }
        } else if (key == "rgbd:camera.intrinsics") {
            expect(6);
            PinholeIntrinsics k;
            const auto w = integer(0), h = integer(1);
            if (w <= 0 || h <= 0 || w > 100000 || h > 100000) throw bad("bad image size");
            k.width = static_cast<int>(w);
            k.height = static_cast<int>(h);
            k.fx = number(2);
            k.fy = number(3);
            k.cx = number(4);
            k.cy = number(5);
            if (!(k.fx > 0 && k.fy > 0)) throw bad("focal lengths must be positive");
            if (view.intrinsics) k.distortion = view.intrinsics->distortion;
            view.intrinsics = k;
        } else if (key == "rgbd:camera.distortion") {
            if (values.empty()) throw bad("missing model");
            Distortion d;
            d.model = std::string(values[0]);
            for (std::size_t i = 1; i < values.size(); ++i) d.coeffs.push_back(number(i));
            try {
                d.check();
            } catch (const InputError& e) {
                throw bad(e.what());
            }
            distortion = d;
        } else if (key == "rgbd:pose.world_from_sensor") {
            expect(12);
            std::array<double, 12> m{};
            for (std::size_t i = 0; i < 12; ++i) m[i] = number(i);
            try {
                pose_from_3x4(m);  // validation only; keep the exact numbers below
            } catch (const InputError& e) {
                throw bad(e.what());
            }
            Pose pose = Pose::Identity();
            for (int r = 0; r < 3; ++r) {
                for (int col = 0; col < 3; ++col) pose.matrix()(r, col) = m[r * 4 + col];
                pose.matrix()(r, 3) = m[r * 4 + 3];
            }
            view.world_from_sensor = pose;
        } else if (key == "rgbd:grid") {
            expect(2);
            const auto w = integer(0), h = integer(1);
            if (w < 0 || h < 0 || w > 100000 || h > 100000) throw bad("bad grid size");
            view.grid_width = static_cast<int>(w);
            view.grid_height = static_cast<int>(h);
        } else if (key == "rgbd:view.source") {
            view.source = std::string(raw_rest);
        } else if (key == "rgbd:history") {
            view.history.emplace_back(raw_rest);
        } else {
            view.extra_comments.push_back(line);
        }
    }
    if (distortion) {
        if (!view.intrinsics)
            throw InputError("rgbd:camera.distortion without rgbd:camera.intrinsics");
        view.intrinsics->distortion = *distortion;
    }
    return view;
}

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
