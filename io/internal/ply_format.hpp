// The PLY vocabulary shared by the stream reader (io/ply_stream.cpp), the comment metadata
// (io/ply_stream_comments.cpp) and the writer (io/ply_stream_writer.cpp): text helpers, the
// eight PLY scalar types with their byte loads and stores, and the parsed header / element
// storage. PLY format: Turk, "The PLY Polygon File Format" (1994). See io/ply_stream.hpp.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "io/internal/text.hpp"
#include "toolkit/enum_names.hpp"
#include "toolkit/error.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::io::internal::ply {

// ---------------------------------------------------------------------------------------
// Small text helpers

inline std::string_view trim(std::string_view s) {
    const auto not_space = [](char c) { return c != ' ' && c != '\t' && c != '\r' && c != '\n'; };
    while (!s.empty() && !not_space(s.front())) s.remove_prefix(1);
    while (!s.empty() && !not_space(s.back())) s.remove_suffix(1);
    return s;
}

inline std::vector<std::string_view> split(std::string_view s) {
    return internal::split_whitespace(s);
}

inline std::optional<double> parse_double(std::string_view s) {
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

inline std::string format_double(double v) {
    char buf[64];
    const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::general, 17);
    return std::string(buf, ptr);
}

// ---------------------------------------------------------------------------------------
// PLY types

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

/// The type names of the PLY specification (what the writer writes) and the sized names
/// (int8 ... float64) that many writers use instead.
constexpr EnumName<PlyType> kTypeNames[] = {
    {PlyType::kInt8, "char"},     {PlyType::kUint8, "uchar"},   {PlyType::kInt16, "short"},
    {PlyType::kUint16, "ushort"}, {PlyType::kInt32, "int"},     {PlyType::kUint32, "uint"},
    {PlyType::kFloat32, "float"}, {PlyType::kFloat64, "double"}};
constexpr EnumName<PlyType> kSizedTypeNames[] = {
    {PlyType::kInt8, "int8"},       {PlyType::kUint8, "uint8"},    {PlyType::kInt16, "int16"},
    {PlyType::kUint16, "uint16"},   {PlyType::kInt32, "int32"},    {PlyType::kUint32, "uint32"},
    {PlyType::kFloat32, "float32"}, {PlyType::kFloat64, "float64"}};

inline std::optional<PlyType> parse_type(std::string_view s) {
    if (const auto t = value_of(kTypeNames, s)) return t;
    return value_of(kSizedTypeNames, s);
}

inline const char* type_name(PlyType t) { return name_of(kTypeNames, t); }

/// Calls `f.template operator()<T>()` with T the C++ type that stores `t` (std::int8_t ...
/// double) and returns its result: one switch for every per-type operation.
template <typename F>
decltype(auto) visit_type(PlyType t, F&& f) {
    switch (t) {
        case PlyType::kInt8:
            return f.template operator()<std::int8_t>();
        case PlyType::kUint8:
            return f.template operator()<std::uint8_t>();
        case PlyType::kInt16:
            return f.template operator()<std::int16_t>();
        case PlyType::kUint16:
            return f.template operator()<std::uint16_t>();
        case PlyType::kInt32:
            return f.template operator()<std::int32_t>();
        case PlyType::kUint32:
            return f.template operator()<std::uint32_t>();
        case PlyType::kFloat32:
            return f.template operator()<float>();
        case PlyType::kFloat64:
            break;
    }
    return f.template operator()<double>();
}

inline std::size_t type_size(PlyType t) {
    return visit_type(t, []<typename T>() -> std::size_t { return sizeof(T); });
}

inline bool is_integer(PlyType t) { return t != PlyType::kFloat32 && t != PlyType::kFloat64; }

template <typename T>
T load(const unsigned char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}

inline double read_value(const unsigned char* p, PlyType t) {
    return visit_type(t, [p]<typename T>() -> double { return load<T>(p); });
}

template <typename T>
void store(unsigned char* p, double v) {
    const T t = static_cast<T>(v);
    std::memcpy(p, &t, sizeof(T));
}

inline void write_value(unsigned char* p, PlyType t, double v) {
    visit_type(t, [p, v]<typename T>() { store<T>(p, v); });
}

/// Range of an integer type, to reject out-of-range ASCII values.
inline bool fits(PlyType t, double v) {
    return visit_type(t, [v]<typename T>() {
        if constexpr (std::is_integral_v<T>)
            return v >= double(std::numeric_limits<T>::min()) &&
                   v <= double(std::numeric_limits<T>::max());
        else
            return true;
    });
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
// Writing

inline std::string pose_text(const Pose& pose) {
    std::string s;
    for (double v : pose_to_3x4(pose)) s += " " + format_double(v);
    return s;
}

inline std::string one_line(std::string s) {
    for (char& c : s)
        if (c == '\n' || c == '\r') c = ' ';
    return s;
}

}  // namespace rgbd::io::internal::ply
