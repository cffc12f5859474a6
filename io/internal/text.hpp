// Small text helpers shared by the io readers (PLY headers, OFF/OBJ/XYZ/PCD lines).
#pragma once

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

}  // namespace rgbd::io::internal
