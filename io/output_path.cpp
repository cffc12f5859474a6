#include "io/output_path.hpp"

#include <system_error>

namespace rgbd::io {

bool writes_in_place(const std::filesystem::path& path) {
    std::error_code ec;
    const std::filesystem::file_status s = std::filesystem::status(path, ec);
    if (ec || !std::filesystem::exists(s)) return false;
    return !std::filesystem::is_regular_file(s) && !std::filesystem::is_directory(s);
}

}  // namespace rgbd::io
