// PCD reader. See io/internal/pcd.hpp.
#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "io/internal/file_text.hpp"
#include "io/internal/pcd.hpp"
#include "io/internal/text.hpp"
#include "toolkit/error.hpp"

namespace rgbd::io::internal {

namespace {

namespace fs = std::filesystem;
std::vector<std::string_view> split(std::string_view s) { return split_whitespace(s); }

/// LZF decompression (liblzf format, as used by PCL's binary_compressed PCD).
bool lzf_decompress(const unsigned char* in, std::size_t in_size, unsigned char* out,
                    std::size_t out_size) {
    const unsigned char* ip = in;
    const unsigned char* const in_end = in + in_size;
    unsigned char* op = out;
    unsigned char* const out_end = out + out_size;
    while (ip < in_end) {
        std::size_t ctrl = *ip++;
        if (ctrl < 32) {  // literal run of ctrl + 1 bytes
            ++ctrl;
            if (op + ctrl > out_end || ip + ctrl > in_end) return false;
            std::memcpy(op, ip, ctrl);
            op += ctrl;
            ip += ctrl;
        } else {  // back reference
            std::size_t len = ctrl >> 5;
            if (len == 7) {
                if (ip >= in_end) return false;
                len += *ip++;
            }
            if (ip >= in_end) return false;
            const std::size_t back = ((ctrl & 0x1f) << 8) + *ip++ + 1;
            len += 2;
            if (back > static_cast<std::size_t>(op - out) || op + len > out_end) return false;
            const unsigned char* ref = op - back;
            for (std::size_t k = 0; k < len; ++k) *op++ = *ref++;  // may overlap
        }
    }
    return op == out_end;
}

struct PcdField {
    std::string name;
    char type = 'F';
    std::size_t size = 4;
    std::size_t count = 1;
    std::size_t offset = 0;  ///< byte offset in a row (binary layout)
};

double pcd_value(const unsigned char* p, char type, std::size_t size) {
    switch (type) {
        case 'F':
            if (size == 4) {
                float v;
                std::memcpy(&v, p, 4);
                return v;
            } else {
                double v;
                std::memcpy(&v, p, 8);
                return v;
            }
        case 'U': {
            std::uint64_t v = 0;
            std::memcpy(&v, p, size);
            return static_cast<double>(v);
        }
        default: {
            std::int64_t v = 0;
            std::memcpy(&v, p, size);
            if (size < 8) {  // sign-extend
                const int shift = 64 - static_cast<int>(size) * 8;
                v = (v << shift) >> shift;
            }
            return static_cast<double>(v);
        }
    }
}

std::uint32_t pcd_packed_color(const unsigned char* p, std::size_t size) {
    std::uint32_t v = 0;
    std::memcpy(&v, p, std::min<std::size_t>(size, 4));
    return v;
}

}  // namespace

PointCloud read_pcd(const fs::path& path) {
    std::ifstream in = open_input(path);
    std::vector<PcdField> fields;
    std::size_t width = 0, height = 1, points = 0;
    bool have_points = false;
    std::string data;
    std::string line;
    std::size_t header_lines = 0;
    while (data.empty()) {
        if (!std::getline(in, line)) fail(path, "truncated PCD header (no DATA line)");
        if (++header_lines > 1000 || line.size() > 100000) fail(path, "not a PCD file");
        const auto t = split(line);
        if (t.empty() || t[0].front() == '#') continue;
        const std::string_view key = t[0];
        if (key == "VERSION" || key == "VIEWPOINT") continue;
        if (key == "FIELDS") {
            fields.clear();
            for (std::size_t k = 1; k < t.size(); ++k) fields.push_back({std::string(t[k])});
        } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
            if (t.size() != fields.size() + 1)
                fail(path, std::string(key) + " has " + std::to_string(t.size() - 1) +
                               " entries for " + std::to_string(fields.size()) + " fields");
            for (std::size_t k = 0; k < fields.size(); ++k) {
                long long v = 0;
                if (key == "TYPE") {
                    if (t[k + 1].size() != 1 ||
                        std::string_view("FUI").find(t[k + 1][0]) == std::string_view::npos)
                        fail(path, "bad TYPE '" + std::string(t[k + 1]) + "'");
                    fields[k].type = t[k + 1][0];
                } else if (!parse_long(t[k + 1], v) || v <= 0 || v > 1 << 20) {
                    fail(path,
                         "bad " + std::string(key) + " entry '" + std::string(t[k + 1]) + "'");
                } else if (key == "SIZE") {
                    if (v != 1 && v != 2 && v != 4 && v != 8) fail(path, "bad SIZE entry");
                    fields[k].size = static_cast<std::size_t>(v);
                } else {
                    fields[k].count = static_cast<std::size_t>(v);
                }
            }
        } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
            long long v = 0;
            if (t.size() != 2 || !parse_long(t[1], v) || v < 0)
                fail(path, "bad " + std::string(key) + " line");
            if (key == "WIDTH") width = static_cast<std::size_t>(v);
            if (key == "HEIGHT") height = static_cast<std::size_t>(v);
            if (key == "POINTS") {
                points = static_cast<std::size_t>(v);
                have_points = true;
            }
        } else if (key == "DATA") {
            if (t.size() != 2) fail(path, "bad DATA line");
            data = std::string(t[1]);
        } else {
            fail(path, "not a PCD file (unexpected header line '" + line.substr(0, 40) + "')");
        }
    }
    if (!have_points) points = width * height;
    if (fields.empty()) fail(path, "PCD header has no FIELDS");
    std::size_t stride = 0;
    for (PcdField& f : fields) {
        if (f.type == 'F' && f.size != 4 && f.size != 8) fail(path, "bad float SIZE");
        f.offset = stride;
        stride += f.size * f.count;
    }
    const auto find = [&](std::string_view n) -> const PcdField* {
        for (const PcdField& f : fields)
            if (f.name == n) return &f;
        return nullptr;
    };
    const PcdField* fx = find("x");
    const PcdField* fy = find("y");
    const PcdField* fz = find("z");
    if (!fx || !fy || !fz) fail(path, "PCD has no x y z fields");
    const PcdField* frgb = find("rgb");
    if (!frgb) frgb = find("rgba");
    const PcdField* fnx = find("normal_x");
    const PcdField* fny = find("normal_y");
    const PcdField* fnz = find("normal_z");
    const bool normals = fnx && fny && fnz;

    // The header can claim any number of points: what the rest of the file can hold bounds
    // them before anything is allocated (binary: stride bytes a point; ascii: at least one
    // byte a value; LZF expands at most about 88 times, a 3-byte reference to 264 bytes).
    std::size_t values_per_point = 0;
    for (const PcdField& f : fields) values_per_point += f.count;
    const std::streamoff here = in.tellg();
    in.seekg(0, std::ios::end);
    const std::streamoff end = in.tellg();
    in.seekg(here);
    const std::size_t remaining =
        here >= 0 && end > here ? static_cast<std::size_t>(end - here) : 0;
    if (points > 0 && stride > std::numeric_limits<std::size_t>::max() / 128 / points)
        fail(path, "POINTS " + std::to_string(points) + " is too large");
    const bool fits = data == "binary"              ? points * stride <= remaining
                      : data == "ascii"             ? points * values_per_point <= remaining
                      : data == "binary_compressed" ? points * stride <= 100 * remaining + 4096
                                                    : true;
    if (!fits)
        fail(path, "truncated: the header announces " + std::to_string(points) + " points, the " +
                       std::to_string(remaining) + " bytes of " + data + " data hold fewer");

    // Bring the data into the binary row layout (row-major, `stride` bytes per point).
    std::vector<unsigned char> rows(points * stride);
    if (data == "ascii") {
        std::string token;
        for (std::size_t i = 0; i < points; ++i) {
            for (const PcdField& f : fields) {
                for (std::size_t c = 0; c < f.count; ++c) {
                    if (!(in >> token))
                        fail(path, "truncated: " + std::to_string(i) + " of " +
                                       std::to_string(points) + " points");
                    unsigned char* p = rows.data() + i * stride + f.offset + c * f.size;
                    double v = 0;
                    if (!parse_double(token, v))
                        fail(path, "point " + std::to_string(i) + ": bad number '" +
                                       token.substr(0, 30) + "'");
                    if (f.type == 'F' && f.size == 4) {
                        const float fv = static_cast<float>(v);
                        std::memcpy(p, &fv, 4);
                    } else if (f.type == 'F') {
                        std::memcpy(p, &v, 8);
                    } else if (f.type == 'U') {
                        const auto u = static_cast<std::uint64_t>(v < 0 ? 0 : v);
                        std::memcpy(p, &u, f.size);
                    } else {
                        const auto s = static_cast<std::int64_t>(v);
                        std::memcpy(p, &s, f.size);
                    }
                }
            }
        }
    } else if (data == "binary") {
        in.read(reinterpret_cast<char*>(rows.data()), static_cast<std::streamsize>(rows.size()));
        if (static_cast<std::size_t>(in.gcount()) != rows.size())
            fail(path, "truncated binary data (" + std::to_string(in.gcount()) + " of " +
                           std::to_string(rows.size()) + " bytes)");
    } else if (data == "binary_compressed") {
        std::uint32_t sizes[2] = {0, 0};
        in.read(reinterpret_cast<char*>(sizes), 8);
        if (in.gcount() != 8) fail(path, "truncated compressed data header");
        if (sizes[1] != rows.size())
            fail(path, "compressed data decompresses to " + std::to_string(sizes[1]) +
                           " bytes, expected " + std::to_string(rows.size()));
        std::vector<unsigned char> compressed(sizes[0]);
        in.read(reinterpret_cast<char*>(compressed.data()), sizes[0]);
        if (static_cast<std::size_t>(in.gcount()) != sizes[0])
            fail(path, "truncated compressed data");
        std::vector<unsigned char> columns(sizes[1]);
        if (!lzf_decompress(compressed.data(), compressed.size(), columns.data(), columns.size()))
            fail(path, "corrupt LZF data");
        // Decompressed data is column-major: all values of field 1, then field 2, ...
        std::size_t at = 0;
        for (const PcdField& f : fields) {
            const std::size_t bytes = f.size * f.count;
            for (std::size_t i = 0; i < points; ++i, at += bytes)
                std::memcpy(rows.data() + i * stride + f.offset, columns.data() + at, bytes);
        }
    } else {
        fail(path, "unsupported PCD DATA '" + data + "'");
    }

    PointCloud cloud;
    const bool organised = height > 1 && width * height == points;
    if (normals) cloud.points.add_normal_map();
    std::optional<PointCloud::ColorMaps> colors;
    if (frgb) colors = cloud.add_colors();
    std::optional<PointCloud::Uint32Map> pixel;
    if (organised) {
        pixel = cloud.add_pixel_map();
        cloud.view.grid_width = static_cast<int>(width);
        cloud.view.grid_height = static_cast<int>(height);
    }
    cloud.points.reserve(points);
    for (std::size_t i = 0; i < points; ++i) {
        const unsigned char* row = rows.data() + i * stride;
        const double x = pcd_value(row + fx->offset, fx->type, fx->size);
        const double y = pcd_value(row + fy->offset, fy->type, fy->size);
        const double z = pcd_value(row + fz->offset, fz->type, fz->size);
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) continue;  // no return
        const auto idx = *cloud.points.insert(Point_3(x, y, z));
        if (normals)
            cloud.points.normal(idx) = {pcd_value(row + fnx->offset, fnx->type, fnx->size),
                                        pcd_value(row + fny->offset, fny->type, fny->size),
                                        pcd_value(row + fnz->offset, fnz->type, fnz->size)};
        if (colors) {
            const std::uint32_t c = pcd_packed_color(row + frgb->offset, frgb->size);
            colors->set(idx, {static_cast<std::uint8_t>((c >> 16) & 0xff),
                              static_cast<std::uint8_t>((c >> 8) & 0xff),
                              static_cast<std::uint8_t>(c & 0xff)});
        }
        if (pixel) (*pixel)[idx] = static_cast<std::uint32_t>(i);
    }
    return cloud;
}

}  // namespace rgbd::io::internal
