// Small text helpers shared by the io readers and writers (PLY headers, OFF/OBJ/XYZ/PCD lines,
// capture folder text files).
#pragma once

#include <charconv>
#include <string>
#include <string_view>
#include <vector>

namespace rgbd::io::internal {

/// Splits a line at spaces, tabs and carriage returns; empty fields are dropped.
inline std::vector<std::string_view> split_whitespace(std::string_view s) {
    std::vector<std::string_view> out;
    std::size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r')) ++i;
        const std::size_t start = i;
        while (i < s.size() && s[i] != ' ' && s[i] != '\t' && s[i] != '\r') ++i;
        if (i > start) out.push_back(s.substr(start, i - start));
    }
    return out;
}

/// A double as text files write it: %.17g, which reads back as the same double.
inline std::string format_exact(double v) {
    char buf[64];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::general, 17);
    return std::string(buf, end);
}

}  // namespace rgbd::io::internal
