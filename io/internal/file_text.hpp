// File helpers shared by the io readers: the "FILE: problem" error, opening an input file with
// a clear error, and whole-token number parses.
#pragma once

#include <charconv>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "toolkit/error.hpp"

namespace rgbd::io::internal {

/// Throws InputError "PATH: problem".
[[noreturn]] inline void fail(const std::filesystem::path& path, const std::string& problem) {
    throw InputError(path.string() + ": " + problem);
}

/// Opens a regular file for binary reading; InputError when missing or a folder, IoError when
/// it cannot be opened.
inline std::ifstream open_input(const std::filesystem::path& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) fail(path, "no such file");
    if (std::filesystem::is_directory(path, ec)) fail(path, "is a folder, not a file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path.string() + ": cannot open for reading");
    return in;
}

/// Whole-token parses (a leading '+' is allowed); false on any junk.
inline bool parse_double(std::string_view s, double& v) {
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && ptr == s.data() + s.size();
}

inline bool parse_long(std::string_view s, long long& v) {
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && ptr == s.data() + s.size();
}

}  // namespace rgbd::io::internal
